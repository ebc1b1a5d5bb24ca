"""Monitoring: the wear estimator (known truth, units, uncertainty, fit) and the loop on a wearing simulated servo."""

from __future__ import annotations

import dataclasses
import json
import math
import time
import tracemalloc

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.errors import DataError
from servoid.excitation import UniformSpec, stream
from servoid.ident.control.compensate import default_band
from servoid.ident.models.wear import GEAR_PLANT, Wear, WearingPlant
from servoid.ident.monitoring.alarms import Bound
from servoid.ident.monitoring.wear_estimator import WearEstimator, WearEstimatorConfig
from servoid.modelfile import ModelFile, load_model
from servoid.monitor_history import MonitorHistory
from servoid.monitor_run import MonitorConfig, compensation_band, read_estimates, run_monitor
from servoid.session import SessionConfig, run_session

NOISE = 0.0337  # the gear plant's noise at SNR 40


def record(n: int, *, seed: int, model=GEAR_PLANT, wear: Wear | None = None, amplitude: float = 2.406, noise=NOISE):
    rng = np.random.default_rng(seed)
    u = rng.uniform(-amplitude, amplitude, n)
    plant = WearingPlant(model, wear or Wear())
    y = np.array([plant.step(v) for v in u]) + rng.normal(0.0, noise, n)
    return u, y


def test_the_tracker_follows_a_growing_dead_zone_with_an_honest_uncertainty():
    u, y = record(60_000, seed=4, wear=Wear(drift=1.3, drift_samples=30_000, drift_start=10_000))
    estimator = WearEstimator(WearEstimatorConfig(reference=GEAR_PLANT, noise_std=NOISE))
    dead = []
    for k, (a, b) in enumerate(zip(u, y)):
        estimator.update(a, b)
        if k >= 45_000 and k % 100 == 0:
            dead.append(estimator.estimate().dead_zone)
    e = estimator.estimate()
    assert abs(np.mean(dead) - 1.3) < 0.01 and e.recoveries == 0
    # the reported std is of the order of the scatter (cautious: the filter expects the parameters to wander)
    assert np.std(dead) < e.dead_zone_std < 4 * np.std(dead)
    assert e.c1 == pytest.approx(0.52, abs=0.02) and e.m2 == pytest.approx(1.5, abs=0.02)
    assert estimator.fit == pytest.approx(1 / 40, rel=0.25)  # at the noise floor: the model explains the rest
    assert estimator.model.dead_zone == pytest.approx(e.dead_zone)


def test_one_setting_fits_every_unit():
    # the same servo read in a unit 100 times smaller (say, centi-units): the estimates scale exactly
    u, y = record(8000, seed=5)
    big = dataclasses.replace(GEAR_PLANT, c1=GEAR_PLANT.c1 * 100, c2=GEAR_PLANT.c2 * 100)
    one = WearEstimator(WearEstimatorConfig(reference=GEAR_PLANT, noise_std=NOISE))
    hundred = WearEstimator(WearEstimatorConfig(reference=big, noise_std=NOISE * 100))
    for a, b in zip(u, y):
        one.update(a, b)
        hundred.update(a * 100, b * 100)
    e1, e100 = one.estimate(), hundred.estimate()
    np.testing.assert_allclose(e100.values[-2:], e1.values[-2:] * 100, rtol=1e-9)
    np.testing.assert_allclose(e100.values[:-2], e1.values[:-2], rtol=1e-9)
    assert e100.dead_zone_std == pytest.approx(e1.dead_zone_std * 100, rel=1e-9)
    # without the normalisation, a q sized for dead zones of 0.05 rad freezes the linear block (see ident/monitoring/wear_estimator.py)


def test_the_fit_waits_for_its_window_and_sees_a_servo_the_model_does_not_explain():
    u, y = record(12_000, seed=6)
    estimator = WearEstimator(WearEstimatorConfig(reference=GEAR_PLANT, noise_std=NOISE, fit_window=5000))
    for a, b in zip(u[:4999], y[:4999]):
        estimator.update(a, b)
    assert math.isnan(estimator.fit) and math.isnan(estimator.estimate().fit)
    for a, b in zip(u[4999:], y[4999:]):
        estimator.update(a, b)
    good = estimator.fit
    # an output with a slow wobble the backlash model cannot produce
    wobble = y + 0.3 * np.sin(np.arange(y.size) * 2 * np.pi / 700)
    off = WearEstimator(WearEstimatorConfig(reference=GEAR_PLANT, noise_std=NOISE, fit_window=5000))
    for a, b in zip(u, wobble):
        off.update(a, b)
    assert good < 0.035 and off.fit > 3 * good


def test_the_history_keeps_the_whole_run_in_constant_memory():
    hist = MonitorHistory(capacity=16)
    for k in range(1000):
        hist.add({"k": k, "t": k / 10, "dead_zone": 1.0})
        assert len(hist) <= 16
    snap = hist.snapshot(bounds=(), unit="rad", source="x", period_s=0.1)
    k = snap.column("k")
    assert k[0] == 0 and k[-1] >= 1000 - 1000 // 16 and np.all(np.diff(k) > 0)
    assert np.all(np.isnan(snap.column("true_m2")))


def test_a_hand_set_band_is_kept_and_the_default_follows_the_model():
    worn = dataclasses.replace(GEAR_PLANT, c1=0.6, c2=0.9)
    default = ModelFile(model=GEAR_PLANT, noise_std=0.01)
    assert compensation_band(default, worn) == pytest.approx(default_band(worn, noise_std=0.01))
    custom = dataclasses.replace(default, band=0.123)
    assert compensation_band(custom, worn) == 0.123


def monitor(url: str, n: int, tmp_path, *, share: float = 0.1, stop: bool = False, on_progress=None):
    with driver_from_url(url) as servo:
        config = MonitorConfig(
            estimator=WearEstimatorConfig(reference=GEAR_PLANT, noise_std=servo.noise_std),
            bounds=(Bound(quantity="dead_zone", low=1 - share, high=1 + share, label="dead zone"),
                    Bound(quantity="m2", low=1.5 * (1 - share), high=1.5 * (1 + share))),
            row_every=500, stop_on_alarm=stop,
        )  # fmt: skip
        events: list[tuple[str, str]] = []
        result = run_monitor(
            servo, stream(UniformSpec(amplitude=2.406), seed=3, n=n), SessionConfig(period_s=1e-3), config,
            model_file=ModelFile(model=GEAR_PLANT, noise_std=servo.noise_std), out=tmp_path, total=n,
            truth_at=servo.truth_at, on_event=lambda kind, line: events.append((kind, line)), on_progress=on_progress,
        )  # fmt: skip
    return result, events


def test_the_monitor_raises_the_alarm_when_the_worn_dead_zone_crosses_its_bound(tmp_path):
    # c1 + c2 from 1.0 to 1.5 over 40 000 samples from sample 5000: the truth crosses 1.1 at sample 13 000
    url = "sim://gear?snr=40&clock=virtual&seed=2&drift=1.5&drift_samples=40000&drift_start=5000"
    result, events = monitor(url, 50_000, tmp_path)
    alarm = result.first_alarm
    assert alarm is not None and alarm.bound.quantity == "dead_zone" and alarm.side == "above"
    assert 13_000 < alarm.since and alarm.sample < 13_000 + 4000  # after the truth crossed, within 4 s at 1 kHz
    alarms = [line for kind, line in events if kind == "alarm"]
    assert len(alarms) == 1 and alarms[0].startswith("ALARM dead zone")
    assert result.counts["ok"] == 50_000 and result.stopped is None and result.session.samples == ()
    # the files: estimates every 500 samples, compensation as it changes, the latest model, the events
    rows, meta = read_estimates(result.files["estimates"])
    assert rows["k"].size == 100 and meta["unit"] == "unit" and rows["k"][-1] == 49_999
    assert np.max(np.abs(rows["dead_zone"] - rows["true_dead_zone"])[rows["k"] > 20_000]) < 0.04
    assert set(rows["alarms"][rows["k"] > alarm.sample]) == {"dead_zone"} and set(rows["alarms"][:20]) == {""}
    comp = [json.loads(line) for line in result.files["compensation"].read_text().splitlines()]
    assert comp[0]["from"] == "model file" and comp[0]["dead_zone"] == pytest.approx(1.0)
    dz = [c["dead_zone"] for c in comp]
    assert len(comp) == result.compensation_updates + 1 >= 15 and dz[-1] == pytest.approx(1.5, abs=0.03)
    assert all(abs(b / a - 1) > 0.02 for a, b in zip(dz, dz[1:]))
    saved = load_model(result.files["model"])
    assert saved.method == "mrgia-tracking" and saved.model.dead_zone == pytest.approx(1.5, abs=0.03)
    assert saved.sample_period_s == 0.001 and saved.servo["wear"]["drift"] == 1.5
    kinds = [json.loads(line)["event"] for line in result.files["events"].read_text().splitlines()]
    assert kinds[0] == "start" and kinds[-1] == "stop" and "alarm" in kinds


def test_no_alarm_without_drift_even_with_tight_bounds(tmp_path):
    result, events = monitor("sim://gear?snr=40&clock=virtual&seed=7", 100_000, tmp_path, share=0.03)
    assert result.events == () and not [e for e in events if e[0] == "alarm"]
    assert abs(result.estimate.dead_zone - 1.0) < 0.02


def test_stop_on_alarm_ends_the_run_soon_after_a_gear_swap(tmp_path):
    url = "sim://gear?snr=40&clock=virtual&seed=1&swap_at=20000&swap_factor=1.2"
    result, _ = monitor(url, 60_000, tmp_path, stop=True)
    assert result.stopped == "alarm" and 20_000 < result.first_alarm.sample < 22_000
    assert result.samples == result.first_alarm.sample + 1  # stopped at once: the input ends there


def test_memory_stays_flat_over_a_long_run(tmp_path):
    traced: dict[int, int] = {}

    def sample(p):
        if p.done >= 5000 and not traced or p.done >= 40_000 and len(traced) == 1:
            traced[p.done] = tracemalloc.get_traced_memory()[0]

    tracemalloc.start()
    try:
        monitor("sim://gear?snr=40&clock=virtual", 41_000, tmp_path, on_progress=sample)
        # the measurement can see growth: a session that keeps its samples grows by ~100 bytes each
        with driver_from_url("sim://gear?clock=virtual") as servo:
            before = tracemalloc.get_traced_memory()[0]
            kept = run_session(servo, np.zeros(5000), SessionConfig(period_s=1e-3))
            grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    (a, early), (b, late) = sorted(traced.items())
    assert b - a >= 30_000
    assert late - early < 20_000  # bytes over 35 000 samples: nothing grows per sample
    assert len(kept) == 5000 and grown > 5000 * 100


def test_read_estimates_rejects_other_files(tmp_path):
    other = tmp_path / "other.csv"
    other.write_text("u,y\n1,2\n")
    with pytest.raises(DataError, match="not an estimates.csv"):
        read_estimates(other)
    with pytest.raises(DataError, match="no such file"):
        read_estimates(tmp_path / "missing.csv")


def test_the_bench_servo_in_rad_is_tracked_with_the_same_settings():
    u, y = record(30_000, seed=8, model=MODEL_PLANT, amplitude=0.2, noise=1e-4,
                  wear=Wear(drift=1.3, drift_samples=10_000, drift_start=5000))  # fmt: skip
    estimator = WearEstimator(WearEstimatorConfig(reference=MODEL_PLANT, noise_std=1e-4))
    for a, b in zip(u, y):
        estimator.update(a, b)
    assert estimator.estimate().dead_zone == pytest.approx(0.05 * 1.3, rel=0.01)


def test_the_live_plot_draws_in_another_process(tmp_path):
    from servoid.plots.monitor import LivePlot

    hist = MonitorHistory()
    for k in range(0, 5000, 100):
        hist.add({"k": k, "t": k / 1000, "dead_zone": 1.0 + k / 1e5, "dead_zone_std": 0.01, "m2": 1.5, "m2_std": 0.01})
    snap = hist.snapshot(bounds=(Bound(quantity="dead_zone", low=0.9, high=1.1),), unit="rad", source="test",
                         period_s=0.001)  # fmt: skip
    path = tmp_path / "live.png"
    live = LivePlot(path)
    try:
        deadline = time.monotonic() + 60
        while not live.submit(snap):  # the process says when it is ready
            assert time.monotonic() < deadline
            time.sleep(0.05)
        assert not live.submit(snap)  # busy drawing (or not yet asking): dropped, never waited for
        while not path.exists():
            assert time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        live.close()
    assert live._proc.returncode == 0 and path.stat().st_size > 10_000


def test_ctrl_c_ends_the_run_with_every_output_complete(tmp_path):
    def until_ctrl_c():
        yield from stream(UniformSpec(amplitude=2.406), seed=3, n=12_345)
        raise KeyboardInterrupt

    with driver_from_url("sim://gear?snr=40&clock=virtual") as servo:
        config = MonitorConfig(
            estimator=WearEstimatorConfig(reference=GEAR_PLANT, noise_std=servo.noise_std), row_every=1000
        )
        result = run_monitor(servo, until_ctrl_c(), SessionConfig(period_s=1e-3), config,
                             model_file=ModelFile(model=GEAR_PLANT), out=tmp_path)  # fmt: skip
        assert not servo.device.plant.enabled  # the torque is off
    assert result.stopped == "interrupted" and result.samples == 12_345
    rows, _ = read_estimates(result.files["estimates"])
    assert list(rows["k"][-2:]) == [11_999, 12_344]  # the last row is the last sample
    stop = json.loads(result.files["events"].read_text().splitlines()[-1])
    assert stop == {"event": "stop", "k": 12_344, "t": 12.344, "samples": 12_345, "reason": "interrupted"}
    assert load_model(result.files["model"]).samples == 12_345
