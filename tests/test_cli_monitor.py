"""``servoid monitor`` from the command line, on the simulated servo in virtual time."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from servoid.cli import main
from servoid.cli.monitor import parse_bounds
from servoid.errors import ConfigError
from servoid.ident.models.wear import GEAR_PLANT
from servoid.ident.monitoring.loop_wear import PLAY_WINDOW_S
from servoid.modelfile import ModelFile, load_model, save_model
from servoid.monitor_run import EXIT_ALARM, read_estimates

GEAR = "sim://gear?snr=40&clock=virtual"


@pytest.fixture
def model(tmp_path):
    """The gear servo's model as `servoid identify` would write it (at 1 kHz, SNR 40)."""
    return save_model(tmp_path / "model.json", ModelFile(model=GEAR_PLANT, noise_std=0.0337, sample_period_s=0.001))


def test_fail_on_alarm_stops_at_a_gear_swap_with_a_clear_line_and_status_3(tmp_path, model, capsys):
    out = tmp_path / "run"
    code = main(["monitor", "--driver", f"{GEAR}&swap_at=20000&swap_factor=1.2", "--model", str(model),
                 "--duration", "60", "--fail-on-alarm", "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == EXIT_ALARM == 3
    last = err.strip().splitlines()[-1]
    assert last.startswith("servoid monitor: stopped on alarm (exit 3): ALARM dead zone c1 + c2")
    assert "ALARM dead zone c1 + c2 = 1.1" in err  # printed when it was raised, with the value
    rows, meta = read_estimates(out / "estimates.csv")
    assert 20_000 < rows["k"][-1] < 22_000  # the run ended soon after the swap (at 1 kHz, the model's rate)
    assert meta["period_s"] == "0.001" and rows["alarms"][-1] == "dead_zone"


def test_a_run_without_wear_raises_nothing_and_summarises_in_json(tmp_path, model, capsys):
    out = tmp_path / "quiet"
    code = main(["monitor", "--driver", GEAR, "--model", str(model), "--duration", "30", "--dead-zone", "0.95,1.05",
                 "--m2", "none", "--fit", "0.05", "--every", "0.5", "--json", "--out", str(out)])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0 and "ALARM" not in captured.err
    summary = json.loads(captured.out)
    assert summary["samples"] == 30_000 and summary["alarms"] == [] and summary["stopped"] is None
    assert summary["estimate"]["dead_zone"] == pytest.approx(1.0, abs=0.02)
    assert summary["estimate"]["fit"] == pytest.approx(1 / 40, rel=0.3)
    assert summary["estimate"]["values"]["m2"] == pytest.approx(1.5, rel=0.02) and summary["unit"] == "unit"
    rows, meta = read_estimates(out / "estimates.csv")
    assert rows["k"].size == 60 and "m2" not in meta["bounds"] and "fit <= 0.05" in meta["bounds"]
    assert set(json.loads(line)["event"] for line in (out / "events.jsonl").read_text().splitlines()) == {
        "start",
        "stop",
    }


def test_a_drift_with_a_plot_raises_the_alarm_and_draws_the_figure(tmp_path, model, capsys):
    plot = tmp_path / "live.png"
    code = main(["monitor", "--driver", f"{GEAR}&drift=1.5&drift_samples=20000", "--model", str(model),
                 "--duration", "25", "--plot", str(plot), "--plot-every", "0.05", "--out", str(tmp_path / "p")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0 and plot.stat().st_size > 10_000 and "ALARM dead zone" in err


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["--dead-zone", "1.2,0.9"], "--dead-zone (='1.2,0.9') must have finite MIN < MAX"),
        (["--m2", "lots"], "--m2 (='lots') must be MIN,MAX"),
        (["--dead-zone", "150%"], "P must lie in (0, 100) %"),
        (["--rate", "500"], "differs from the rate the model was identified at (1000 Hz)"),
        (["--duration", "-1"], "--duration (=-1) must be > 0"),
        (["--fit", "0"], "--fit (=0) must be a positive NRMSE"),
        (["--persist", "0"], "persist"),
        (["--excitation", "uniform:amplitude=-1"], "amplitude"),
    ],
)
def test_bad_options_are_one_line_errors(tmp_path, model, capsys, argv, fragment):
    code = main(["monitor", "--driver", GEAR, "--model", str(model), "--out", str(tmp_path / "x"), *argv])
    err = capsys.readouterr().err
    assert code == 2 and fragment in err and "Traceback" not in err


def test_a_model_in_another_unit_is_refused(tmp_path, capsys):
    counts = save_model(tmp_path / "m.json", ModelFile(model=GEAR_PLANT, output_unit="counts"))
    code = main(["monitor", "--driver", GEAR, "--model", str(counts), "--duration", "1", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and "the model is in 'counts'" in err
    code = main(["monitor", "--driver", GEAR, "--model", str(tmp_path / "none.json")])
    assert code == 2 and "no such model file" in capsys.readouterr().err


def test_bounds_parse_absolute_relative_or_none():
    b = parse_bounds("10%", quantity="dead_zone", label="dz", reference=2.0, unit="rad")
    assert (b.low, b.high, b.unit) == (pytest.approx(1.8), pytest.approx(2.2), "rad")
    assert parse_bounds("0.5, 0.7", quantity="m2", label="m2", reference=1.0).high == 0.7
    assert parse_bounds("none", quantity="m2", label="m2", reference=1.0) is None
    with pytest.raises(ConfigError, match="--dead-zone"):
        parse_bounds("1", quantity="dead_zone", label="dz", reference=1.0)
    assert dataclasses.is_dataclass(b)


def test_the_wear_estimator_runs_at_the_model_rate_on_the_decimated_stream(tmp_path, model, capsys):
    # --rate twice the model's: the session samples at 2 kHz, the MRGIA sees every 2nd sample (anti-aliased)
    out = tmp_path / "fast"
    code = main(["monitor", "--driver", GEAR, "--model", str(model), "--rate", "2000", "--duration", "1",
                 "--json", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    _, meta = read_estimates(out / "estimates.csv")
    assert meta["decimate"] == "2" and meta["period_s"] == "0.0005"
    assert json.loads((out / "model.json").read_text())["units"]["sample_period_s"] == pytest.approx(0.001)
    # without --rate: the live run's own rate, stated in the model file (its probe's design)
    live = save_model(
        tmp_path / "live.json", dataclasses.replace(load_model(model), extra={"decimation": {"factor": 4}})
    )
    code = main(["monitor", "--driver", GEAR, "--model", str(live), "--duration", "0.5", "--json",
                 "--out", str(tmp_path / "live")])  # fmt: skip
    assert code == 0
    _, meta = read_estimates(tmp_path / "live" / "estimates.csv")
    assert meta["decimate"] == "4" and float(meta["period_s"]) == pytest.approx(0.00025)
    assert main(["monitor", "--driver", GEAR, "--model", str(model), "--rate", "1500", "--out", str(out)]) == 2
    assert "not a whole multiple" in capsys.readouterr().err


def test_a_servo_loop_model_is_followed_by_its_window_refit_and_alarms_after_the_play_steps_up(tmp_path, capsys):
    # the model file as a live identify of the XM430 twin writes it (the play inside the loop, 20 s of servo time:
    # on 12 s the places of the play can tie, and the answer's play scattered -3 ... -20 % over the branches that
    # built it; its window plays then scatter enough (36 %) that the CUSUM's threshold hides a 1.6x step)
    sines = "gentle:amplitude=0.1,accel=0.000408,spread=8"
    ident = tmp_path / "ident"
    assert main(["identify", "--driver", "sim://xm430?clock=virtual", "--rate", "140", "--samples", "2800",
                 "--no-probe", "--excitation", sines, "--no-plots", "--json", "--out", str(ident)]) == 0  # fmt: skip
    saved = json.loads(capsys.readouterr().out)
    assert saved["form"] == "servo_loop"
    # the wearing twin: its play x1.6 from 40 s on (sample 5600 at 140 Hz), after the baseline (10 s of the whole
    # loop, 20 s of the play alone), driven by the monitor's steady sine (the identification's amplitude at half its
    # acceleration, from the start: one --excitation; with the identification's sines throughout the window plays
    # scatter 14-16 % with the segments, and the alarm came 18.5 s after the step, or not within the run)
    steady = "gentle:amplitude=0.1,accel=0.000204,spread=1,smallest=1"
    out = tmp_path / "watch"
    code = main(["monitor", "--driver", "sim://xm430?clock=virtual&swap_at=5600&swap_factor=1.6", "--model",
                 str(ident / "model.json"), "--duration", "60", "--excitation", steady, "--json", "--out", str(out)])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    summary = json.loads(captured.out)
    assert summary["estimator"] == "window" and summary["structure"] == saved["structure"]
    # one alarm, above, after the step and before the run ends; how soon is benchmarks/monitor_loop.py's to measure
    # (it follows the baseline's scatter: 1.0 s here; with the identification's sines 18.5 s with numpy 2.4 / scipy
    # 1.17 and the search's profile restart, 9.75 s before it, none within the run with the play fit's finer sub-steps)
    # ``since`` is the CUSUM's change-point estimate (the check after its sum last stood at 0): a window play drawn
    # high just before the step can start the run, so it may lead the step by up to one window (PLAY_WINDOW_S)
    raised = [a for a in summary["alarms"] if a["raised"]]
    lead = PLAY_WINDOW_S * 140
    assert len(raised) == 1 and 5600 < raised[0]["sample"] < 8400 and raised[0]["side"] == "above"
    assert 5600 - lead < raised[0]["since"] <= raised[0]["sample"]
    rows, meta = read_estimates(out / "estimates.csv")
    assert "window" in meta["servoid monitor"] and rows["true_play"][-1] == pytest.approx(1.6 * rows["true_play"][0])
    assert rows["dead_zone"][-1] > 1.2 * rows["dead_zone"][0]  # the window plays followed the step up
    # the wear since monitoring began: each window play over the baseline's median, empty before the baseline
    rel = np.asarray(rows["dead_zone_rel"])
    based = ~np.isnan(np.asarray(rows["dead_zone_std"]))
    assert np.all(np.isnan(rel[~based])) and based.any() and not np.isnan(rel[based]).any()
    median = np.asarray(rows["dead_zone"])[based] / rel[based]
    np.testing.assert_allclose(median, median[0], rtol=1e-12)  # one median, the baseline's
    assert rel[-1] > 1.2
    # the bound in % follows the monitor's own baseline: a doubt about the file's play re-baselines, and says so
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    doubts = [e for e in events if e["event"] == "doubt"]
    assert [e["action"] for e in doubts] == (["rebaseline"] if summary["doubt"] else [])
    # a file that says its play is not identifiable, with an absolute bound: refused in one line after the first refit
    data = json.loads((ident / "model.json").read_text())
    data["structure"]["identifiable"] = False
    (tmp_path / "unplaced.json").write_text(json.dumps(data))
    refused = tmp_path / "refused"
    code = main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(tmp_path / "unplaced.json"),
                 "--duration", "30", "--excitation", sines, "--dead-zone", "0.002,0.008", "--out", str(refused)])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and "refused to monitor: the model file says its play is not identifiable" in err[-1]
    events = [json.loads(line) for line in (refused / "events.jsonl").read_text().splitlines()]
    assert [e["action"] for e in events if e["event"] == "doubt"] == ["refuse"]
    assert events[-1]["event"] == "stop" and events[-1]["t"] < 11.0  # stopped at the first refit (10 s)


def _designed_loop_file(tmp_path, structure=None, slow_accel=0.0):
    """A servo-loop model file (play in the loop, 100 Hz) with the design ``identify --driver`` writes: gentle
    sines of +/-0.08 rad at up to 8 rad/s^2, at a live run of 200 Hz (its acceleration per sample^2 there);
    ``structure`` another place of the play, ``slow_accel`` its slow phase's acceleration (rad/s^2)."""
    from servoid.ident import BacklashModel
    from servoid.ident.models.servo_loop import ServoLoopModel
    from servoid.ident.models.structure_names import PLAY_IN_LOOP, SERVO_LOOP

    place = structure or PLAY_IN_LOOP
    loop = ServoLoopModel(structure=place, sample_period_s=0.01, kp=20.0, kv=150.0, c1=0.004, c2=0.003)
    black_box = BacklashModel(a=(-0.9,), b=(0.1,), delay=1, m2=1.0, c1=0.004, c2=0.003)
    design = {"factor": 4, "shape": "gentle", "hold": 4, "amplitude": 0.08, "accel": 8.0 / 200.0**2,
              "slow_accel": slow_accel / 200.0**2, "slow_part": 0.0 if slow_accel == 0.0 else 0.4, "margin": 0.5,
              "estimator_rate_hz": 50.0, "reasons": {}}  # fmt: skip
    content = ModelFile(model=black_box, output_unit="rad", input_unit="rad", sample_period_s=0.01, band=0.001,
                        structure=place, form=SERVO_LOOP, identifiable=True, play=loop.play,
                        loop=loop.params(), extra={"design": design})  # fmt: skip
    return save_model(tmp_path / "loop.json", content)


def test_the_steady_sine_of_a_play_outside_the_loop_stays_at_the_slow_phases_acceleration_at_the_same_frequency(
    tmp_path,
):
    # the CiA 402 twin's live file: half the fast phase's acceleration let its load coast (no alarm in 20 s)
    from servoid.excitation.generate import sample
    from servoid.excitation.monitor_input import SINE, monitor_spec
    from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
    from servoid.modelfile import load_model
    from servoid.monitor_loop import design_sines

    np = pytest.importorskip("numpy")
    outside = design_sines(load_model(_designed_loop_file(tmp_path, OUTPUT_BACKLASH, 1.5)), 0.01)
    inside = design_sines(load_model(_designed_loop_file(tmp_path, PLAY_IN_LOOP, 1.5)), 0.01)
    assert outside is not None and inside is not None
    assert outside[:2] == pytest.approx((0.08, 8.0e-4)) and outside[2] == pytest.approx(1.5e-4)
    assert inside[:2] == outside[:2] and inside[2] == float("inf")  # the play read on the load: no bound
    slow = monitor_spec(SINE, *outside[:2], coast=outside[2])
    half = monitor_spec(SINE, *inside[:2], coast=inside[2])
    assert half.accel == pytest.approx(4.0e-4) and half.amplitude == pytest.approx(0.08)
    assert slow.accel == pytest.approx(1.5e-4) and slow.amplitude == pytest.approx(0.08 * 1.5 / 4.0)
    u, v = sample(slow, 3000, seed=0), sample(half, 3000, seed=0)
    accel = np.abs(np.diff(u, 2))  # (but where one segment meets the next)
    assert np.mean(accel > 1.5e-4 * 1.001) < 0.02 and np.quantile(accel, 0.9) > 0.9 * 1.5e-4
    assert np.max(np.abs(u)) == pytest.approx(0.03, rel=0.01)
    assert _reversals(u) == _reversals(v)  # the same reversals a second: what a window counts


def _commands(monkeypatch):
    """Every command the session sends (as limited and rounded by the driver), in order."""
    import numpy as np

    from servoid.drivers.base import Driver

    sent: list[float] = []
    begin = Driver.begin_exchange

    def spy(self, u, *, slot=None):
        pending = begin(self, u, slot=slot)
        sent.append(pending.command)
        return pending

    monkeypatch.setattr(Driver, "begin_exchange", spy)
    return sent, np


def _reversals(u):
    import numpy as np

    step = np.diff(u)
    step = step[step != 0.0]
    return int(np.count_nonzero(np.diff(np.sign(step))))


def _events(out):
    return [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]


def test_a_servo_loop_model_is_driven_by_the_identifications_sines_then_one_steady_sine(tmp_path, monkeypatch, capsys):
    # what benchmarks/monitor_loop.py measured: the first fit's 10 s on the identification's gentle sines, then one
    # sine at their largest amplitude and half their highest acceleration (SINE_ACCEL_SHARE: 4 rad/s^2 here, 1.13 Hz
    # at 0.08 rad); --input cycled (the file's play sits inside the loop): the sine's amplitude a count / N smaller
    # each half-period over N values (CYCLE_STEPS), the count the XM430 twin's encoder's, read from the first fit's readings
    from servoid.excitation.gentle import segment_end
    from servoid.excitation.monitor_input import IDENT, monitor_spec

    model = _designed_loop_file(tmp_path)
    sent, np = _commands(monkeypatch)
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(model), "--duration", "22",
                 "--input", "cycled", "--out", str(tmp_path / "sine")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    hz = np.sqrt(4.0 / 0.08) / (2.0 * np.pi)
    assert f"then one steady sine +/-0.08 rad at {hz:.3g} Hz" in err
    u = np.array(sent)
    assert u.size == 2200
    # the sines run on to the end of the segment that holds the 10th second: back at the offset, no step
    cut = segment_end(monitor_spec(IDENT, 0.08, 8.0 * 0.01**2), 0, 1000)
    assert 1000 <= cut <= 1600 and abs(u[cut - 1]) < 0.08 * 0.2 and abs(u[cut]) < 0.08 * 0.2
    assert np.max(np.abs(np.diff(u[cut - 50 : cut + 50]))) <= np.max(np.abs(np.diff(u[cut:])))
    head, tail = u[:1000], u[cut : cut + 600]
    # the first 10 s: gentle sines of several amplitudes, none beyond the design's, at most its acceleration (but
    # where one segment meets the next: the velocity changes there)
    accel = np.abs(np.diff(u, 2)) / 0.01**2
    assert np.max(np.abs(head)) <= 0.08 and np.mean(accel[:998] > 8.0 * 1.001) < 0.02
    peaks = [np.max(np.abs(head[i : i + 100])) for i in range(0, 1000, 100)]
    assert max(peaks) > 2.0 * min(peaks)
    # then the steady sine: its amplitude, its reversals (two a period), its acceleration; no other segment kind
    assert np.max(np.abs(tail)) == pytest.approx(0.08, rel=0.01)
    assert _reversals(tail) / 6.0 == pytest.approx(2.0 * hz, rel=0.1)
    assert np.mean(accel[cut:] > 4.0 * 1.001) < 0.02 and np.quantile(accel[cut:], 0.9) > 0.9 * 4.0
    peaks = [np.max(np.abs(tail[i : i + 100])) for i in range(0, 600, 100)]
    assert min(peaks) > 0.95 * 0.08
    _, meta = read_estimates(tmp_path / "sine" / "estimates.csv")
    assert "spread=1.0" in meta["excitation"] and "steady sine" in meta["input"]
    # cycled: the peaks, half-period by half-period, a quarter count lower each over four values, then again
    count = 2.0 * np.pi / 4096.0
    from servoid.excitation.monitor_input import CYCLE_STEPS as N

    assert meta["input_kind"] == "cycled" and f"cycled: its amplitude a count / {N} smaller" in err
    assert "the encoder's count 0.00153398 rad, from the first fit's" in err
    [said] = [e for e in _events(tmp_path / "sine") if e["event"] == "input"]
    assert said["input"] == "cycled" and said["count"] == pytest.approx(count, rel=1e-9) and said["k"] >= cut
    # (a peak between two samples of a whole half-period holds two equal ones: the turns of the non-zero steps)
    step = np.diff(u[cut:])
    moves = np.flatnonzero(np.abs(step) > 1e-12)
    turns = moves[:-1][np.sign(step[moves[1:]]) != np.sign(step[moves[:-1]])] + cut + 1
    depth = (0.08 - np.abs(u[turns])) / (count / N)
    np.testing.assert_allclose(depth, np.arange(depth.size) % N, atol=0.2)  # within the peak sample's rounding
    # the default (off: CYCLED_DEFAULT) and --input steady: one amplitude, the input before, command for command
    from servoid.excitation.monitor_input import monitor_stream

    sent.clear()
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(model), "--duration", "11",
                 "--out", str(tmp_path / "steady")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "one amplitude (the default; --input cycled" in err and "cycles its amplitude" not in err
    old = np.fromiter(monitor_stream(0.08, 8.0 * 0.01**2, 1000, seed=0), dtype=np.float64, count=1100)
    np.testing.assert_array_equal(np.array(sent), old)
    _, meta = read_estimates(tmp_path / "steady" / "estimates.csv")
    assert meta["input_kind"] == "steady" and not [e for e in _events(tmp_path / "steady") if e["event"] == "input"]


def test_a_play_outside_the_loop_keeps_the_steady_sine_and_too_few_readings_fall_back_to_it(tmp_path, monkeypatch,
                                                                                            capsys):  # fmt: skip
    # a play outside the loop: its loop closes on the motor's encoder, whose count grid the readings do not show;
    # even with the cycled sine as the default (CYCLED_DEFAULT on) it keeps the steady one
    import servoid.excitation.monitor_input as monitor_input
    from servoid.excitation.monitor_input import monitor_stream
    from servoid.ident.models.structure_names import OUTPUT_BACKLASH

    monkeypatch.setattr(monitor_input, "CYCLED_DEFAULT", True)

    outside = _designed_loop_file(tmp_path, OUTPUT_BACKLASH)
    sent, np = _commands(monkeypatch)
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(outside), "--duration", "11",
                 "--out", str(tmp_path / "outside")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "one amplitude (the default; --input cycled" in err
    old = np.fromiter(monitor_stream(0.08, 8.0 * 0.01**2, 1000, seed=0), dtype=np.float64, count=1100)
    np.testing.assert_array_equal(np.array(sent), old)  # the input before, command for command
    _, meta = read_estimates(tmp_path / "outside" / "estimates.csv")
    assert meta["input_kind"] == "steady" and not [e for e in _events(tmp_path / "outside") if e["event"] == "input"]
    # the same setting on a file whose play sits inside the loop: the cycled sine without --input
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(_designed_loop_file(tmp_path)),
                 "--duration", "10.5", "--out", str(tmp_path / "inside")]) == 0  # fmt: skip
    assert f"cycled: its amplitude a count / {monitor_input.CYCLE_STEPS} smaller" in capsys.readouterr().err
    assert [e["input"] for e in _events(tmp_path / "inside") if e["event"] == "input"] == ["cycled"]
    monkeypatch.setattr(monitor_input, "CYCLED_DEFAULT", False)
    # a play inside the loop whose first fit's readings show no count (the sines inside one count of the encoder:
    # the horn hardly moves): the steady sine, and the output says why
    sent.clear()
    out = tmp_path / "still"
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual&amplitude=0.0012", "--model",
                 str(_designed_loop_file(tmp_path)), "--duration", "10.6", "--input", "cycled", "--json",
                 "--out", str(out)]) == 0  # fmt: skip
    captured = capsys.readouterr()
    assert "the steady sine at one amplitude, not cycled: too few readings to see the encoder's count" in captured.err
    summary = json.loads(captured.out)
    assert summary["input_kind"] == "steady" and summary["grid"]["count"] is None
    [said] = [e for e in _events(out) if e["event"] == "input"]
    assert said["input"] == "steady" and "too few readings" in said["why"]
    old = np.fromiter(monitor_stream(0.0012, 8.0 * 0.01**2, 1000, seed=0), dtype=np.float64, count=1060)
    np.testing.assert_array_equal(np.array(sent), old)


def test_input_applies_only_to_the_servo_loop_monitors_own_sine(tmp_path, model, capsys):
    assert main(["monitor", "--driver", GEAR, "--model", str(model), "--input", "cycled", "--duration", "1",
                 "--out", str(tmp_path / "mrgia")]) == 2  # fmt: skip
    assert "--input (=cycled) chooses the steady sine of the servo-loop monitor" in capsys.readouterr().err
    loop = _designed_loop_file(tmp_path)
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(loop), "--input", "steady",
                 "--excitation", "uniform:amplitude=0.03", "--duration", "1", "--out", str(tmp_path / "own")]) == 2  # fmt: skip
    assert "it does not apply with --operating or --excitation" in capsys.readouterr().err


def test_the_steady_sine_stays_inside_the_drivers_limits(tmp_path, monkeypatch, capsys):
    model = _designed_loop_file(tmp_path)
    sent, np = _commands(monkeypatch)
    driver = "sim://xm430?clock=virtual&centre=0.2&amplitude=0.05&max_step=0.004"
    assert main(["monitor", "--driver", driver, "--model", str(model), "--duration", "12", "--input", "cycled",
                 "--out", str(tmp_path / "limited")]) == 0  # fmt: skip
    assert "steady sine +/-0.05 rad" in capsys.readouterr().err  # the design's 0.08 capped by the band
    u = np.array(sent)
    # from the servo's place at enable (0) to the band at the rate limit, then inside it
    inside = int(np.argmax(u >= 0.15))
    assert 0 < inside <= 0.15 / 0.004 + 1 and np.all(np.abs(u[inside:] - 0.2) <= 0.05 + 1e-12)
    assert np.max(np.abs(np.diff(u))) <= 0.004 + 1e-12
    assert np.max(u[1000:]) == pytest.approx(0.25, abs=0.001)
    # the sine cycled (--input cycled): its amplitude only goes down, so the band holds it
    assert [e["input"] for e in _events(tmp_path / "limited") if e["event"] == "input"] == ["cycled"]


def test_excitation_overrides_the_steady_sine_and_a_file_without_a_design_says_so(tmp_path, monkeypatch, capsys):
    model = _designed_loop_file(tmp_path)
    sent, np = _commands(monkeypatch)
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(model), "--duration", "12",
                 "--excitation", "uniform:amplitude=0.03", "--out", str(tmp_path / "own")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "input: operating none, excitation uniform:amplitude=0.03" in err and "steady sine" not in err
    u = np.array(sent)
    assert np.max(np.abs(u)) <= 0.03 and _reversals(u[1000:]) > 50  # white noise: a reversal most samples
    # the same file without its design (identify --data): the monitor's default before, and the line says why
    data = json.loads(model.read_text())
    del data["design"]
    (tmp_path / "plain.json").write_text(json.dumps(data))
    sent.clear()
    assert main(["monitor", "--driver", "sim://xm430?clock=virtual", "--model", str(tmp_path / "plain.json"),
                 "--duration", "12", "--out", str(tmp_path / "plain")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "excitation uniform:" in err and "holds no gentle-sines design" in err
    assert _reversals(np.array(sent)[1000:]) > 50


def test_a_horn_play_sized_on_a_short_record_is_named_and_a_long_record_or_a_massless_loop_is_not() -> None:
    # the horn stage sizes a play in the loop on a compliant contact only on about 40 s (the STS3215 twin: -23 % on 20 s)
    import dataclasses

    from servoid.ident import BacklashModel
    from servoid.ident.models.servo_loop import ServoLoopModel
    from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP, SERVO_LOOP
    from servoid.monitor_loop import HORN_RECORD_S, short_horn

    horn = ServoLoopModel(structure=PLAY_IN_LOOP, sample_period_s=0.005, kp=20.0, kv=150.0, c1=0.005, c2=0.005,
                          mu=0.03, al=20.0, wc=500.0, zeta=0.1)  # fmt: skip
    black_box = BacklashModel(a=(-0.9,), b=(0.1,), delay=1, m2=1.0, c1=0.005, c2=0.005)
    content = ModelFile(model=black_box, output_unit="rad", input_unit="rad", sample_period_s=0.005,
                        structure=PLAY_IN_LOOP, form=SERVO_LOOP, play=horn.play, loop=horn.params(), samples=4000)  # fmt: skip
    assert short_horn(content) == pytest.approx(20.0)
    assert short_horn(dataclasses.replace(content, samples=int(HORN_RECORD_S / 0.005))) is None
    massless = dataclasses.replace(horn, mu=0.0, al=0.0, wc=0.0, zeta=0.0)
    assert short_horn(dataclasses.replace(content, loop=massless.params())) is None
    outside = dataclasses.replace(horn, structure=OUTPUT_BACKLASH)
    assert short_horn(dataclasses.replace(content, structure=OUTPUT_BACKLASH, loop=outside.params())) is None
    assert short_horn(dataclasses.replace(content, samples=None)) is None
