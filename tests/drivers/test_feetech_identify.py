"""``servoid identify --driver 'feetech://...?id=1,2'``: one bus session, a model per joint, one table."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid.cli import main
from servoid.drivers.feetech.emulator import EmulatorProcess
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.modelfile import load_model
from servoid.recording import read_recording


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_two_joints_of_one_bus_give_two_models_near_the_plant(tmp_path, capsys):
    # the emulator takes each goal as one sample (no own clock), so a loaded host changes the timing
    # of the run but not the plant seen: late samples may be used, and no guard is needed (a missed
    # slot, which a loaded host makes, is the one departure: the plant does not step while the
    # record holds the command, hence the loose tolerance)
    with EmulatorProcess([3, 5], servo="model") as emu:
        code = main(["identify", "--driver", emu.url([3, 5], latency_ms=100), "--samples", "1000", "--rate", "200",
                     "--use-late", "--guard", "0", "--allow-lost", "--joints", "together", "--no-plots", "--json",
                     "--out", str(tmp_path)])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["joints_excitation"] == "together"
    assert [j["id"] for j in out["joints"]] == [3, 5]
    for joint in out["joints"]:  # each joint answers with its verdict and its own lost-sample count (1000 slots)
        assert isinstance(joint["identifiable"], bool) and joint["structure"] and joint["lost"]["samples"] == 1000
        assert joint["budget"]["share_s"] > 0 and isinstance(joint["budget"]["cut"], list)  # its share of 60 s
    assert out["budget"]["wall_s"] == 120 and out["budget"]["seconds"] > 5  # 60 s a joint by default
    rec = read_recording(tmp_path / "recording.csv", u_column="u_5", y_column="y_5")
    assert rec.metadata["joints"] == "3,5" and len(rec) == 1000
    for servo_id in (3, 5):
        content = load_model(tmp_path / f"joint_{servo_id}" / "model.json")
        # the estimator's own plant behind the protocol: its play within 25 % (whole-count encoder, missed slots),
        # or withheld by the verdict (a missed slot leaves the plant still while the record moves on, which
        # colours the residual): never a confident wrong play
        if content.identifiable is not False:
            assert content.model.dead_zone == pytest.approx(MODEL_PLANT.dead_zone, rel=0.25), servo_id
    assert np.isfinite(rec.y).sum() > 500


def test_the_bus_default_is_gentle_sines_at_8_rad_s2_and_needs_rad():
    from servoid.cli._live_bus import gentle_default
    from servoid.errors import ConfigError
    from servoid.excitation import parse_spec

    spec = parse_spec(gentle_default(None, 200.0, "rad"))
    assert spec.amplitude == 0.1 and spec.accel == pytest.approx(8.0 / 200.0**2)
    assert parse_spec(gentle_default(0.05, 100.0, "rad")).amplitude == 0.05
    with pytest.raises(ConfigError, match="'deg'.*--excitation"):
        gentle_default(None, 200.0, "deg")


def test_a_bus_session_past_its_wall_budget_cuts_each_joint_says_so_and_leaves_the_torque_off(tmp_path, capsys):
    from servoid.cli._live import IDENTIFY_CUT
    from servoid.drivers.feetech.emulator import FeetechEmulator

    from .dxl_helpers import TEST_LATENCY_MS

    # two joints one after the other, 0.75 s of servo time each, in a budget of 2.1 s: the run takes at least its
    # 1.5 s (the sampler keeps the rate), so no joint's share of the 0.6 s left (at most) outlasts its outputs' 1 s:
    # each identification is stopped at its first fit evaluation, answers with the best made by then (withheld) or
    # none, and says so
    with FeetechEmulator(ids=[1, 2], servo="model") as emu:
        code = main(["identify", "--driver", emu.url([1, 2], latency_ms=TEST_LATENCY_MS), "--samples", "150",
                     "--rate", "200", "--use-late", "--guard", "0", "--allow-lost", "--budget", "2.1", "--no-plots",
                     "--json", "--out", str(tmp_path)])  # fmt: skip
        torque = [s.torque for s in emu.bus.servos]
    captured = capsys.readouterr()
    out = json.loads(captured.out, parse_constant=lambda c: pytest.fail(f"not strict JSON: {c}"))
    assert torque == [False, False]
    assert out["budget"]["wall_s"] == 2.1 and out["budget"]["joints_cut"] == [1, 2]
    assert "shared among the joints" in out["budget"]["bounds"]
    for joint in out["joints"]:
        assert joint["budget"]["cut"] == [IDENTIFY_CUT] and joint["budget"]["share_s"] < 0.6
        if "error" in joint:  # no answer made by then: the refusal names the cut
            assert code == 1 and "cut by the wall budget" in joint["error"]
        else:  # the best made by then, withheld, the cut among its reasons
            assert joint["identifiable"] is False
            assert any("stopped at the wall budget's deadline" in r for r in joint["reasons"])
            assert f"joint {joint['id']}: the wall budget (2.1 s" in captured.err  # its warning line
    assert "leaves the joints no time within --budget 2.1 s" in " ".join(captured.err.split())
