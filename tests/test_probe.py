"""The probe, the design from it, the online verdict and the lost-sample refusal, on simulated servos."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid.cli import main
from servoid.drivers import driver_from_url
from servoid.drivers.servos import MODEL_PLANTS
from servoid.errors import ModelError
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import free_run
from servoid.ident.online.decimate import DecimatingEstimator, decimate_record, decimation_factor, slow_denominator
from servoid.ident.online.mrgia import MRGIA, MRGIAConfig, convergence_margin, run_mrgia
from servoid.ident.online.probe_design import GENTLE_SHARE, design_live
from servoid.ident.online.verdict import judge_online
from servoid.modelfile import ModelFile, save_model
from servoid.session import SessionConfig
from servoid.session.probe import run_probe

RATE = 200.0


def _probe(url: str, amplitude: float | None = None):  # type: ignore[no-untyped-def]
    driver = driver_from_url(url)
    with driver:
        return run_probe(driver, amplitude or driver.reference_amplitude, SessionConfig(period_s=1 / RATE))[0]


def test_probe_of_the_exact_plant_finds_its_play_and_a_safe_rate() -> None:
    plant = MODEL_PLANTS["model"].model
    probe = _probe("sim://model?clock=virtual&snr=40&seed=2")
    assert abs(probe.play / plant.dead_zone - 1) < 0.1  # m2 = 1: the hysteresis at rest is c1 + c2
    assert probe.noise_std > 0 and probe.lost == 0 and not probe.saturated
    design = design_live(probe, RATE)
    assert design.factor >= decimation_factor(plant.a)  # the probe's model asks at least what the truth needs
    assert convergence_margin(slow_denominator(plant.a, design.factor)) >= 0
    assert design.hold % design.factor == 0 and design.hold >= 3 * design.factor
    # gentle sines by default, their fastest full-amplitude segment at GENTLE_SHARE of the probe's bandwidth
    f_top = np.sqrt(design.accel / design.amplitude) / (2 * np.pi) * RATE
    assert design.shape == "gentle" and f_top == pytest.approx(GENTLE_SHARE * probe.bandwidth_hz)
    # ... after a slow phase, gentler still, for a play outside the loop
    assert design.slow_spec() is not None and design.slow_accel < design.accel and 0 < design.slow_part < 1
    held = design_live(probe, RATE, hold=5)
    assert held.shape == "steps" and held.spec().startswith("steps:") and held.hold % held.factor == 0
    assert held.slow_spec() is None


def test_the_design_never_saturates_a_drive_the_probe_saw_saturate(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    probe = _probe("sim://odrive?clock=virtual")
    assert probe.saturated  # the ODrive twin's current limit caps its speed on the largest steps
    design = design_live(probe, RATE)
    assert design.amplitude <= probe.amplitude / 2
    # the designed levels step by up to 2 A: a probe of amplitude A makes exactly those steps
    assert not _probe("sim://odrive?clock=virtual", design.amplitude).saturated
    # servoid excite --design told about the same servo (its probe in model.json) stays below it too
    model = BacklashModel(a=(-0.8,), b=(0.2,), delay=1, m2=1.0, c1=0.02, c2=0.02)
    path = save_model(tmp_path / "model.json", ModelFile(model=model, extra={"probe": probe.to_dict()}))
    argv = ["excite", "--design", "--range", "-1", "1", "--model", str(path), "--json", "--no-plot",
            "--out", str(tmp_path / "e.csv")]  # fmt: skip
    assert main(argv) == 0
    free = json.loads(capsys.readouterr().out)["design"]["spec"]
    assert main([*argv, "--probe", str(path), "--force"]) == 0
    capped = json.loads(capsys.readouterr().out)["design"]["spec"]
    amp = float(capped.split("amplitude=")[1].split(",")[0])
    assert amp <= probe.amplitude / 2 < float(free.split("amplitude=")[1].split(",")[0])


def test_verdict_settles_the_converged_run_and_not_the_stuck_one() -> None:
    from scipy.signal import cont2discrete

    w = 2 * np.pi * 5.0
    num, den, _ = cont2discrete(([w * w], [1, 1.4 * w, w * w]), 1 / 250.0)  # a 5 Hz loop at 50x
    plant = BacklashModel(a=tuple(den[1:]), b=tuple(num[0][1:]), delay=1, m2=1.0, c1=0.004, c2=0.004)
    k = decimation_factor(plant.a)
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(-0.05, 0.05, 700), 3 * k)
    y = free_run(plant, u)
    config = MRGIAConfig(na=2, nb=1, delay=1)
    fast = run_mrgia(u, y, config, record_every=20)
    try:
        fast_fit: float | None = float(np.std(y - free_run(fast.model, u)) / np.std(y))
    except ModelError:  # the stuck estimate is not even a model
        fast_fit = None
    stuck = judge_online(fast, fast_fit, plant, 0.0)
    assert not stuck.settled and stuck.reasons
    est = DecimatingEstimator(MRGIA(config), k, record_every=5)
    for uk, yk in zip(u, y):
        est.update(uk, yk)
    slow = est.mrgia_result()
    assert slow is not None
    us, ys, _, _ = decimate_record(u, y, k)
    slow_fit = float(np.std(ys - free_run(slow.model, us)) / np.std(ys))
    verdict = judge_online(slow, slow_fit, plant, 0.0)
    assert verdict.settled, verdict.reasons
    assert json.loads(json.dumps(verdict.to_dict()))["settled"] is True


@pytest.mark.parametrize("allow", [False, True])
def test_identify_refuses_when_too_many_samples_are_lost(tmp_path, capsys, allow) -> None:  # type: ignore[no-untyped-def]
    argv = ["identify", "--json", "--driver", "sim://model?clock=virtual&drop=0.02&seed=3", "--samples", "2000",
            "--no-probe", "--no-plots", "--out", str(tmp_path)] + (["--allow-lost"] if allow else [])  # fmt: skip
    code = main(argv)
    out, err = capsys.readouterr()
    if not allow:
        assert (
            code == 2 and "could not be used" in err and "--max-lost 0.2" in err and len(err.strip().splitlines()) == 1
        )
        assert not (tmp_path / "model.json").exists() and (tmp_path / "recording.csv").exists()
    else:
        assert code == 0
        lost = json.loads(out)["lost"]
        assert lost["share_unusable"] > 0.2 and lost["usable"] + lost["not_measured"] <= lost["samples"]


def saved_cap(obj: dict) -> float:  # type: ignore[type-arg]
    """The amplitude the probe in ``obj`` allows (the design's cap)."""
    from servoid.ident.online.probe import ProbeResult
    from servoid.ident.online.probe_design import amplitude_cap

    return amplitude_cap(ProbeResult.from_dict(obj["probe"]))[0]


def test_live_identify_probes_designs_and_judges_by_default(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    code = main(["identify", "--json", "--driver", "sim://model?clock=virtual&snr=40&seed=1", "--rate", "200",
                 "--samples", "4000", "--no-plots", "--out", str(tmp_path)])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0, err
    obj = json.loads(out)
    design, online = obj["design"], obj["online"]
    assert obj["decimation"]["factor"] == design["factor"] > 1
    # gentle sines by default (they change inside a group: the estimator sees the group's anti-aliased mean)
    assert design["shape"] == "gentle" and 0 < design["accel"] and design["amplitude"] <= saved_cap(obj)
    assert obj["samples"] == 4000 // design["factor"]
    assert online["settled"] == (not online["reasons"])
    saved = json.loads((tmp_path / "model.json").read_text())
    assert saved["probe"]["samples"] > 0 and saved["online"] == online
    assert (tmp_path / "probe.csv").exists()
    # one answer, and where it came from: the servo loop's search (the online estimate a candidate), or the black box
    answer = obj["answer"]
    assert answer["play"] == obj["play"] and saved["answer"] == answer
    assert answer["source"] in (("loop_search", "loop_online") if obj["form"] == "servo_loop" else ("offline_fit",))


def test_the_probe_says_the_play_cannot_be_seen_on_a_servo_read_on_its_motor() -> None:
    # the CiA 402 twin read on its output: the hysteresis at rest is its play; read on its motor
    # encoder (the host reads the shaft an ODrive's estimates come from) the play lies beyond the readings
    output = _probe("sim://cia402?clock=virtual")
    motor = _probe("sim://cia402?clock=virtual&output_encoder=motor")
    assert output.readings == "output" and output.play > 0 and "cannot be seen" not in output.rows()[4][1]
    assert motor.readings == "motor" and "cannot be seen: the readings are the motor's" in motor.rows()[4][1]
    assert type(motor).from_dict(json.loads(json.dumps(motor.to_dict()))) == motor
