"""``servoid identify --driver`` and ``servoid emulate serial``: the live path from the command line."""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import time

import numpy as np
import pytest

from servoid.cli import main
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.ident import BacklashModel
from servoid.modelfile import load_model
from servoid.recording import read_recording


def run_json(capsys, *argv):
    code = main(["identify", "--json", *argv])
    captured = capsys.readouterr()
    return code, (json.loads(captured.out) if code == 0 else None), captured.err


def test_a_live_run_on_the_simulated_servo_writes_what_an_offline_run_writes(tmp_path, capsys):
    code, obj, _ = run_json(capsys, "--driver", "sim://model?clock=virtual&seed=1&jitter=0.0002", "--rate", "1000",
                            "--samples", "2000", "--no-probe", "--out", str(tmp_path))  # fmt: skip
    assert code == 0
    acq = obj["acquisition"]
    assert acq["samples"] == 2000 and acq["counts"]["late"] > 0 and acq["counts"]["timeout"] == 0
    assert obj["max_relative_error"] < 1e-6  # noise-free: the used samples identify the plant exactly
    for key in ("recording", "model", "convergence_plot", "fit_plot", "backlash_plot"):
        assert (tmp_path / obj["outputs"][key].split("/")[-1]).stat().st_size > 0
    saved = load_model(tmp_path / "model.json")
    assert saved.servo["driver"] == "sim" and saved.sample_period_s == pytest.approx(0.001)
    rec = read_recording(tmp_path / "recording.csv")
    assert rec.status is not None and len(rec) == 2000
    # the recording identifies again offline with the live run's orders, leaving out the same samples
    code, again, _ = run_json(capsys, "--data", str(tmp_path / "recording.csv"), "--out", str(tmp_path / "b"),
                              "--no-plots", "--na", "2", "--nb", "0", "--delay", "1")  # fmt: skip
    assert code == 0 and again["warnings"] == obj["warnings"]
    np.testing.assert_allclose(again["model"]["c2"], obj["model"]["c2"], rtol=1e-9)


def test_a_live_run_on_the_default_twin_says_what_is_true_of_it(tmp_path, capsys):
    code, obj, _ = run_json(capsys, "--driver", "sim://?clock=virtual", "--samples", "300", "--out", str(tmp_path),
                            "--no-plots", "--no-probe")  # fmt: skip
    assert code == 0 and "truth" not in obj and "max_relative_error" not in obj  # no pseudo-Wiener model is true of it
    twin = obj["twin_truth"]
    assert twin["name"] == "xm430" and twin["play_rad"] == pytest.approx(np.radians(0.25))
    assert (twin["loop_encoder"], twin["output_encoder"]) == ("load", "load")
    assert obj["budget"]["wall_s"] is None and obj["budget"]["cut"] == []  # a virtual clock is not timed
    main(
        [
            "identify",
            "--driver",
            "sim://?clock=virtual",
            "--samples",
            "300",
            "--out",
            str(tmp_path),
            "--no-plots",
            "--no-probe",
        ]
    )
    assert "the twin xm430: true play 0.00436332 rad at the output" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["--driver", "sim://?bogus=1"], "unknown option(s) bogus"),
        (["--driver", "sim://", "--data", "x.csv"], "not both"),
        (["--driver", "sim://", "--snr", "40"], "put it in the URL"),
        (["--driver", "sim://", "--rate", "0"], "--rate (=0) must lie in"),
        (["--driver", "tcp://host"], "unknown driver scheme 'tcp'"),
        (["--driver", "sim://", "--budget", "1"], "--budget (=1) must be a number of wall seconds > 2"),
        # a bus session checks its budget and --max-lost before it opens the port
        (["--driver", "feetech:///dev/null?id=1,2", "--budget", "nan"], "--budget (=nan) must be a number"),
        (["--driver", "dxl:///dev/null?id=1,2", "--max-lost", "2"], "--max-lost (=2) must lie in [0, 1]"),
    ],
)
def test_bad_live_options_are_one_line_errors(tmp_path, capsys, argv, fragment):
    code, _, err = run_json(capsys, *argv, "--out", str(tmp_path))
    assert code == 2 and fragment in err and "Traceback" not in err


def test_a_run_whose_servo_loop_search_the_wall_budget_cut_answers_with_the_black_box_withheld(tmp_path, capsys):
    # a real clock, 1.5 s of servo time, a budget that leaves nothing after the run: the answer's search is stopped
    # at its first evaluation and no window refit had ended to answer instead; identification's refinement of the
    # black box too (its stop 1 s before the budget's end): the MRGIA's estimate answers, withheld
    code, obj, _ = run_json(capsys, "--driver", "sim://", "--samples", "300", "--no-probe", "--no-plots",
                            "--budget", "2.5", "--out", str(tmp_path))  # fmt: skip
    assert code == 0 and obj["form"] != "servo_loop" and not obj["identifiable"] and obj["method"] == "mrgia"
    assert obj["reasons"][0].startswith("cut by the wall budget: the servo-loop search")
    assert any("refinement from the mrgia start stopped at the wall budget's deadline" in r for r in obj["reasons"])
    assert obj["budget"]["wall_s"] == 2.5 and obj["budget"]["cut"][-2].startswith("the answer: the search")
    assert obj["budget"]["cut"][-1].startswith("identification's own fits")


def test_a_port_that_does_not_exist_is_a_driver_error(tmp_path, capsys):
    code, _, err = run_json(capsys, "--driver", "serial:///dev/no-such-tty", "--out", str(tmp_path))
    assert code == 1 and "cannot open /dev/no-such-tty" in err


@pytest.mark.slow
def test_emulate_serial_in_one_process_identify_driver_in_another(tmp_path):
    """The issue's "done when": the emulated bench servo, identified over its pseudo-terminal."""
    emulator = subprocess.Popen([sys.executable, "-m", "servoid", "emulate", "serial", "--servo", "model"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)  # fmt: skip
    try:
        # Raw reads: a buffered readline() after select() can pull several lines
        # into Python's buffer, after which select() never fires for the rest.
        fd = emulator.stdout.fileno()
        printed = b""
        deadline = time.monotonic() + 60
        url = None
        while url is None and time.monotonic() < deadline:
            if not select.select([fd], [], [], 1.0)[0]:
                continue
            chunk = os.read(fd, 4096)
            if not chunk:  # the emulator exited
                break
            printed += chunk
            url = next((ln.split()[-1] for ln in printed.decode().splitlines() if ln.strip().startswith("url")), None)
        if url is None:
            emulator.terminate()
            _, err = emulator.communicate(timeout=10)
            pytest.fail(f"the emulator printed no url: stdout {printed.decode()!r}, stderr {err.decode()!r}")
        assert url.startswith("serial:///dev/")
        done = subprocess.run([sys.executable, "-m", "servoid", "identify", "--driver", url, "--rate", "500",
                               "--samples", "2500", "--json", "--no-plots", "--no-probe", "--allow-lost", "--out", str(tmp_path)],
                              capture_output=True, text=True, timeout=120)  # fmt: skip
        assert done.returncode == 0, done.stderr
        obj = json.loads(done.stdout)
        model = BacklashModel.from_dict(obj["model"])
        assert model.max_relative_error(MODEL_PLANT) < 0.01, obj["acquisition"]
        assert obj["acquisition"]["frames_rejected"] == 0 and obj["acquisition"]["counts"]["ok"] > 500
    finally:
        emulator.terminate()
        emulator.wait(timeout=10)


def test_a_live_twin_with_lost_samples_gets_one_servo_loop_answer_the_online_one_a_candidate(tmp_path, capsys):
    # the live record's mask (lost readings, their guard windows) no longer skips the second structure; the
    # servo-loop answer is the offline search on the whole record with the online window refit as a candidate
    code, obj, err = run_json(capsys, "--driver", "sim://xm430?clock=virtual&drop=0.005&seed=3", "--rate", "200",
                              "--samples", "2400", "--no-probe", "--no-plots", "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    assert obj["lost"]["not_measured"] > 0 and obj["lost"]["usable"] < 2400
    loop = obj["second_structure"]
    assert loop is not None and set(loop["validation_nrmse"]) == {"output_backlash", "play_in_loop"}
    answer, refined = obj["answer"], obj["online_loop"]["refined"]["choice"]
    assert answer["play"] == obj["play"]
    # the answer's search ran on the run's first three quarters while the rest was sampled, and the answer took it
    early = obj["early_search"]
    assert early["started"] and early["at_samples"] == 1800 and early["samples"] <= 1800
    assert obj["online_loop"]["refined"]["search"]["play"] == early["play"]
    if obj["form"] == "servo_loop":  # the answer is the search's, or the online estimate's where it won the search
        won = obj["online_loop"]["refined"]["online_won"]
        assert answer["source"] == ("loop_online" if won else "loop_search") and obj["online"]["estimator"] == "window"
        assert obj["structure"] == loop["structure"] == refined["structure"]
        assert obj["play"] == loop["play"] == refined["play"]
        assert answer["gap"] == pytest.approx(obj["online"]["online_gap"] / obj["play"] - 1.0)
        assert answer["online_settled"] == obj["online"]["settled"]
        low, high = obj["play_interval"]
        if low is None:  # withheld: the fit is too far above its floor for an interval, and the output says why
            assert high is None and "floor" in obj["play_interval_reason"]
        else:
            assert low <= obj["play"] <= high
    else:
        assert answer["source"] == "offline_fit"
    assert isinstance(obj["identifiable"], bool) and "not fitted" not in (obj["reason"] or "")
    saved = json.loads((tmp_path / "model.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert (saved["structure"]["name"], saved["structure"]["form"]) == (obj["structure"], obj["form"])
    assert saved["answer"] == answer


def test_a_live_record_whose_first_samples_were_lost_keeps_the_session_s_online_estimate(tmp_path, capsys):
    # seed 34 loses the run's first samples (and their guard window): the record starts at the first measured
    # one, and identification refines the session's MRGIA estimate instead of running the MRGIA again
    code, obj, err = run_json(capsys, "--driver", "sim://xm430?clock=virtual&drop=0.03&seed=34", "--rate", "200",
                              "--samples", "600", "--no-probe", "--no-plots", "--allow-lost", "--max-lost", "1",
                              "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    session = obj["lost"]["samples"]
    assert obj["samples"] < session  # the record starts after the lost samples
    assert obj["mrgia"]["samples"] == session and obj["mrgia"]["updates"] <= obj["lost"]["usable"]
