"""Recordings on disk: written as samples arrive, read back, a cut-off line survived."""

import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from servoid.errors import DataError
from servoid.recording import RecordingWriter, read_recording, write_recording


def test_roundtrip_keeps_values_metadata_and_ignores_other_columns(tmp_path):
    rng = np.random.default_rng(0)
    u, y = rng.normal(size=100), rng.normal(size=100)
    t = np.arange(100) * 0.002
    p = write_recording(
        tmp_path / "r.csv",
        {"t": t, "u": u, "y": y, "temp": np.ones(100)},
        metadata={"unit": "rad", "source": "bench 3"},
    )
    rec = read_recording(p)
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y) and np.array_equal(rec.t, t)
    assert rec.metadata == {"unit": "rad", "source": "bench 3"}
    assert rec.sample_period == pytest.approx(0.002)


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("a,b\n1,2\n", "missing column(s) 'u', 'y'; the header has 'a', 'b'"),
        ("u,y\n", "no data rows"),
        ("", "no header row"),
        ("u,y\n1,2\n3,x\n", "line 3, column 'y': 'x' is not a number"),
        ("# unit: rad\nu,y\n1,2\n3,nan\n", "line 4, column 'y': 'nan' is not finite"),
        ("u,y\n1,2\n3\n", "line 3: 1 fields, the header has 2"),
    ],
)
def test_bad_files_name_the_problem(tmp_path, text, fragment):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(DataError) as info:
        read_recording(p)
    assert fragment in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match="no such CSV file"):
        read_recording(tmp_path / "nope.csv")


def test_a_cut_off_last_line_is_dropped_with_a_note(tmp_path):
    p = tmp_path / "cut.csv"
    p.write_text("u,y\n1,2\n3,4\n5,4.")
    rec = read_recording(p)
    assert rec.u.tolist() == [1, 3, 5]  # '4.' parses: kept
    p.write_text("u,y\n1,2\n3,4\n5,")
    rec = read_recording(p)
    assert rec.u.tolist() == [1, 3] and "truncated" in rec.notes[0]


def test_writer_keeps_every_row_when_the_process_is_killed(tmp_path):
    path = tmp_path / "live.csv"
    script = textwrap.dedent(
        f"""
        import time
        from servoid.recording import RecordingWriter
        w = RecordingWriter({str(path)!r}, ["t", "u", "y"], metadata={{"unit": "rad"}})
        k = 0
        while True:
            w.append(k * 0.001, float(k), float(-k))
            k += 1
            if k == 500:
                print("ready", flush=True)
            time.sleep(0.0002)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    rec = read_recording(path)
    assert len(rec) >= 500
    assert np.array_equal(rec.u, np.arange(len(rec), dtype=float))
    assert np.array_equal(rec.y, -rec.u)


def test_writer_checks_rows_and_closes_once(tmp_path):
    with RecordingWriter(tmp_path / "w.csv", ["u", "y"]) as w:
        with pytest.raises(DataError, match="a row needs 2 values"):
            w.append(1.0)
        w.append(1.0, 2.0)
    w.close()
    with pytest.raises(DataError, match="closed"):
        w.append(1.0, 2.0)
    assert read_recording(tmp_path / "w.csv").u.tolist() == [1.0]
