"""``servoid batch``: a fleet's recordings on a Dask cluster and on local workers, one table, resumable, failures isolated."""

import csv
import json
from dataclasses import replace

import numpy as np
import pytest

from servoid.batch import servo_id_of, time_of
from servoid.cli import main
from servoid.ident import PAPER_PLANT, simulate
from servoid.modelfile import load_model
from servoid.recording import write_recording

pytest.importorskip("dask.distributed")
pyarrow_parquet = pytest.importorskip("pyarrow.parquet")

#: Two joints; j1's play grows by 0.2 per day over three nightly recordings, j2's stays.
FLEET = {
    "j1-night1": ("j1", "2026-03-01T02:00:00+0000", 1.5),
    "j1-night2": ("j1", "2026-03-02T02:00:00+0000", 1.7),
    "j1-night3": ("j1", "2026-03-03T02:00:00+0000", 1.9),
    "j2-night1": ("j2", "2026-03-01T02:00:00+0000", 1.0),
}


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    rng = np.random.default_rng(18)
    for name, (servo, started, play) in FLEET.items():
        plant = replace(PAPER_PLANT, c1=0.4 * play, c2=0.6 * play)
        sim = simulate(plant, rng.uniform(-3.0, 3.0, 1500))
        write_recording(folder / f"{name}.csv", {"u": sim.u, "y": sim.y},
                        metadata={"servo_id": servo, "started": started, "unit": "rad"})  # fmt: skip
    (folder / "broken.csv").write_text("u,y\n0.1,0.2\nx,0.3\n", encoding="utf-8")
    return folder


@pytest.fixture(scope="module")
def cluster():
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as c:
        yield c.scheduler_address


def run_json(capsys, *argv):
    code = main(["batch", "--json", *argv])
    captured = capsys.readouterr()
    return code, json.loads(captured.out), captured.err


def comparable(table):
    return [{k: v for k, v in row.items() if k != "model"} for row in table]


def test_a_fleet_on_a_cluster_then_resumed_then_locally(fleet, cluster, tmp_path, capsys):
    code, obj, err = run_json(capsys, str(fleet), "--cluster", cluster, "--out", str(tmp_path / "a"))
    assert code == 0
    rows = {r["recording"].rsplit("/", 1)[-1]: r for r in obj["table"]}
    assert rows["broken.csv"]["error"] and "'x' is not a number" in rows["broken.csv"]["error"]
    assert "broken.csv" in err  # reported, and the others went on
    for name, (servo, _, play) in FLEET.items():
        row = rows[f"{name}.csv"]
        assert row["error"] is None and row["servo_id"] == servo
        assert row["play"] == pytest.approx(play, rel=1e-4)  # noise-free: recovered
        assert load_model(row["model"]).model.dead_zone == pytest.approx(row["play"])
        assert row["structure"] and row["unit"] == "rad" and row["fit_nrmse"] < 1e-3
    assert rows["j1-night1.csv"]["play_trend_per_day"] == pytest.approx(0.2, rel=1e-3)
    assert rows["j1-night1.csv"]["trend_recordings"] == 3 and rows["j2-night1.csv"]["play_trend_per_day"] is None
    assert rows["j1-night2.csv"]["time"] == "2026-03-02T02:00:00Z"

    with open(tmp_path / "a" / "fleet.csv", encoding="utf-8") as fh:
        from_csv = list(csv.DictReader(fh))
    from_parquet = pyarrow_parquet.read_table(tmp_path / "a" / "fleet.parquet").to_pylist()
    assert [r["recording"] for r in from_csv] == [r["recording"] for r in obj["table"]]
    assert [r["play"] for r in from_parquet] == [r["play"] for r in obj["table"]]
    assert [float(r["play"]) for r in from_csv if r["play"]] == [r["play"] for r in obj["table"] if r["play"]]

    # resumed: what is done is skipped, the failed recording is tried again
    code, again, err = run_json(capsys, str(fleet), "--cluster", cluster, "--out", str(tmp_path / "a"))
    assert "4 of 5 recordings already done" in err
    assert comparable(again["table"]) == comparable(obj["table"])

    # local worker processes: the same table
    code, local, _ = run_json(capsys, str(fleet), "--workers", "1", "--out", str(tmp_path / "b"))
    assert code == 0 and comparable(local["table"]) == comparable(obj["table"])


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--cluster", "localhost:1"], "is not a scheduler address"),
        (["--workers", "0"], "--workers (=0) must be 1 to 256"),
        (["--memory-per-worker", "lots"], "is not a size such as 2GB"),
    ],
)
def test_bad_options_are_one_line(fleet, tmp_path, capsys, argv, fragment):
    assert main(["batch", str(fleet / "j2-night1.csv"), "--out", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err


def test_servo_id_and_time_from_metadata_or_name(tmp_path):
    assert servo_id_of("logs/bam_xl330_raw_2026-01-15_10h28m10.json", {}) == "bam_xl330_raw"
    assert servo_id_of("logs/anything.csv", {"servo_id": "arm2/wrist"}) == "arm2/wrist"
    assert time_of("bam_xl330_raw_2026-01-15_10h28m10.json", {}) == "2026-01-15T10:28:10Z"
    assert time_of("x.csv", {"started": "2026-03-01T03:00:00+0100"}) == "2026-03-01T02:00:00Z"
    f = tmp_path / "plain.csv"
    f.write_text("u,y\n", encoding="utf-8")
    assert time_of(f, {}).startswith(str(np.datetime64("today", "Y")))


def test_each_job_fits_on_one_thread_whatever_servoid_threads_says(fleet, monkeypatch):
    # the workers already run one recording per core: a fit's own threads would oversubscribe the fleet
    from servoid import batch
    from servoid.ident.offline import _threads
    from servoid.readers import ReadOptions

    def report(rec, config):
        raise ValueError(f"threads {_threads.threads()}")

    monkeypatch.setenv(_threads.ENV, "4")
    monkeypatch.setattr(batch, "_identify", report)
    done = batch.identify_file(str(fleet / "j2-night1.csv"), ReadOptions(), None)
    assert done.row["error"] == "ValueError: threads 1"
    assert _threads.threads() == 4  # only inside the job
