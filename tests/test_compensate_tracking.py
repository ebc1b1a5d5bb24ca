"""Feedforward, tracking metrics, the closed loop on the simulated servo, and ``servoid compensate``."""

import json

import numpy as np
import pytest

from servoid.cli import main
from servoid.errors import ConfigError, ModelError
from servoid.ident import PAPER_PLANT, BacklashModel, simulate
from servoid.ident.control.compensate import InverseParams
from servoid.ident.control.compensation_study import (
    ARMS,
    Improvement,
    compensation_study,
    default_resolution,
    perturbed,
)
from servoid.ident.control.feedforward import LinearInverse
from servoid.ident.control.references import amplitude_limit, reference_suite
from servoid.ident.control.tracking import (
    Sensor,
    TrackingController,
    default_integral_gain,
    simulate_tracking,
    tracking_metrics,
)
from servoid.modelfile import ModelFile


def _linear_x(model, u):
    return simulate(model, u).x


@pytest.mark.parametrize("b, delay", [((0.8,), 1), ((0.5, 0.3), 2), ((0.0, 0.6, 0.2), 1)])
def test_minimum_phase_feedforward_is_the_exact_inverse(b, delay):
    model = BacklashModel(a=(0.45, 0.55), b=b, delay=delay, m2=1.5, c1=0.5, c2=1.0)
    ff = LinearInverse(model)
    assert ff.uncancelled_zeros == ()
    rng = np.random.default_rng(0)
    x_d = np.cumsum(rng.normal(0, 0.1, 300))
    ahead = np.concatenate([x_d, np.zeros(ff.preview)])
    # x_d(k) for k < preview is 0 (the model rests); the command for sample k wants x_d(k + preview)
    u = np.array([ff.step(v) for v in ahead[ff.preview : ff.preview + x_d.size]])
    x = _linear_x(model, u)
    np.testing.assert_allclose(x[ff.preview :], x_d[ff.preview :], atol=1e-9)
    assert ff.preview == delay + (1 if b[0] == 0.0 else 0)


def test_non_minimum_phase_feedforward_is_zero_phase_with_unit_dc_gain():
    # b0 + b1 q^-1 with a zero at -1.5: the exact inverse would blow up
    model = BacklashModel(a=(-0.6,), b=(0.2, 0.3), delay=1, m2=1.0, c1=0.1, c2=0.1)
    ff = LinearInverse(model)
    assert len(ff.uncancelled_zeros) == 1 and abs(ff.uncancelled_zeros[0] + 1.5) < 1e-12
    assert ff.preview == 2
    n = 2000
    k = np.arange(n + ff.preview)
    x_d = np.sin(2 * np.pi * k / 100)
    u = np.array([ff.step(v) for v in x_d[ff.preview :]])
    assert np.max(np.abs(u)) < 10  # bounded
    x = _linear_x(model, u)
    tail = slice(n // 2, n)
    lag = np.argmax(np.correlate(x[tail], x_d[:n][tail], mode="full")) - (n // 2 - 1)
    assert lag == 0  # zero phase error
    assert np.std(x[tail]) == pytest.approx(np.std(x_d[:n][tail]), rel=0.02)  # gain ~1 at low frequency
    const = LinearInverse(model)
    u_const = [const.step(1.0) for _ in range(400)]
    assert _linear_x(model, np.array(u_const))[-1] == pytest.approx(1.0, rel=1e-6)  # unit DC gain


def test_feedforward_refuses_a_block_without_dc_gain():
    with pytest.raises(ModelError, match=r"zero at z = 1 \(sum\(b\) = 0\)"):
        LinearInverse(BacklashModel(a=(0.5,), b=(1.0, -1.0), delay=1, m2=1.0, c1=0.1, c2=0.1))


def test_dead_time_metric_on_known_signals():
    r = np.concatenate([np.linspace(0, 1, 51), np.linspace(1, -1, 101)[1:]])
    y_late = np.concatenate([np.full(7, 0.0), r[:-7]])  # the output is r seven samples late
    m = tracking_metrics(r, y_late, threshold=0.05)
    assert m.reversals == 1 and m.dead_time == 7.0 and m.censored == 0
    held = np.minimum(r, 1.0)
    held[50:] = 1.0  # never turns back
    m = tracking_metrics(r, held, threshold=0.05)
    assert m.censored == 1 and m.dead_time == 100 - 2  # time to the end, minus the reference's own 2 samples
    assert tracking_metrics(r, r, threshold=0.05).dead_time == 0.0
    with pytest.raises(ConfigError, match="differ in length"):
        tracking_metrics(r, r[:-1], threshold=0.05)


def test_controller_with_exact_model_tracks_exactly_and_uncompensated_does_not():
    ref = reference_suite(PAPER_PLANT, samples=300)[0].values
    inv = InverseParams.from_model(PAPER_PLANT, band=0.0)
    good = simulate_tracking(PAPER_PLANT, TrackingController(PAPER_PLANT, inverse=inv), ref, threshold=0.03)
    bad = simulate_tracking(PAPER_PLANT, TrackingController(PAPER_PLANT, inverse=None), ref, threshold=0.03)
    assert good.metrics.rms_error < 1e-9 and good.metrics.dead_time == 0.0  # no noise, no quantisation
    assert bad.metrics.rms_error > 0.05 and bad.metrics.dead_time > 10
    assert good.compensated and not bad.compensated


def test_controller_checks_its_inputs():
    with pytest.raises(ConfigError, match=r"upcoming has 3 values, the preview needs r\(0\) .. r\(0\)"):
        TrackingController(PAPER_PLANT, inverse=None, upcoming=[0, 0, 0])
    with pytest.raises(ConfigError, match=r"integral_gain \(=-0.1\) must be >= 0"):
        TrackingController(PAPER_PLANT, inverse=None, integral_gain=-0.1)
    assert default_integral_gain(1) == 0.25
    ref = reference_suite(PAPER_PLANT, samples=120)[0].values
    with pytest.raises(ConfigError, match=r"diverged at sample \d+ .*integral_gain \(=5\) is too high"):
        simulate_tracking(PAPER_PLANT, TrackingController(PAPER_PLANT, inverse=None, integral_gain=5.0), ref,
                          threshold=0.03)  # fmt: skip


def test_study_shows_compensation_and_its_robustness():
    sensor = Sensor(resolution=0.0075, noise_std=0.01, seed=3)
    study = compensation_study(PAPER_PLANT, band=0.03, sensor=sensor, changes=(-0.1, 0.2),
                               references=reference_suite(PAPER_PLANT, samples=300))  # fmt: skip
    before, after, naive = (study.summary(a) for a in ("uncompensated", "compensated", "naive"))
    assert study.rms_improvement(before, after).ratio > 10
    assert after.dead_time < 1.0 < 5.0 < before.dead_time
    # with noise fed back, the naive inverse throws the motor across the play; the band calms it:
    # the motor's travel beyond what the uncompensated servo needs shrinks by more than 3x
    assert naive.motor_travel - before.motor_travel > 3 * (after.motor_travel - before.motor_travel) > 0
    by_label = {p.label: p for p in study.perturbations}
    assert set(by_label) == {"c1,c2 -10%", "c1,c2 +20%", "all -10%", "all +20%"}
    under = by_label["c1,c2 -10%"].summaries
    assert study.rms_improvement(under["uncompensated"], under["compensated"]).ratio > 3
    assert by_label["c1,c2 +20%"].model.c1 == pytest.approx(0.6)


def test_perturbation_and_floors():
    assert perturbed(PAPER_PLANT, "all parameters", -0.1).a == pytest.approx((0.405, 0.495))
    with pytest.raises(ModelError, match="unstable"):
        perturbed(BacklashModel(a=(0.95,), b=(1.0,), delay=1, m2=1.0, c1=0.1, c2=0.1), "all parameters", 0.1)
    with pytest.raises(ModelError, match="family"):
        perturbed(PAPER_PLANT, "linear", 0.1)
    # a gain the nominal loop survives but a perturbed one does not: that row says so, the study goes on
    study = compensation_study(PAPER_PLANT, band=0.03, integral_gain=0.9, changes=(-0.1, 0.1),
                               references=reference_suite(PAPER_PLANT, samples=120))  # fmt: skip
    diverged = [p for p in study.perturbations if not p.summaries]
    assert diverged and all("diverged" in p.note for p in diverged)
    assert len(diverged) < len(study.perturbations)
    assert str(Improvement.of(1.0, 1e-6, 0.01)) == ">=100x"
    assert str(Improvement.of(1.0, 0.1, 0.01)) == "10x"
    assert default_resolution(PAPER_PLANT, "counts") == 1.0
    assert default_resolution(PAPER_PLANT, "rad") == pytest.approx(1.5 / 200)


def test_reference_suite_respects_the_crossing_of_the_lines():
    refs = reference_suite(PAPER_PLANT)
    limit = amplitude_limit(PAPER_PLANT)
    assert limit == pytest.approx(2.25)  # lines cross at y = -4.5
    assert all(np.max(np.abs(r.values)) <= limit + 1e-12 for r in refs)
    assert all(r.values[0] == 0.0 for r in refs) and len(refs) == 5
    assert amplitude_limit(BacklashModel(a=(0.5,), b=(1.0,), delay=1, m2=1.0, c1=0.1, c2=0.1)) is None


def test_cli_compensate_json_and_plots(tmp_path, capsys):
    path = tmp_path / "model.json"
    path.write_text(ModelFile(model=PAPER_PLANT, output_unit="rad", band=0.03).to_json())
    code = main(["compensate", str(path), "--json", "--samples", "240", "--out", str(tmp_path / "plots")])
    out = capsys.readouterr().out
    assert code == 0
    obj = json.loads(out)
    assert obj["rms_ratio"] > 10 and obj["band"] == 0.03 and obj["resolution"] == pytest.approx(0.0075)
    assert len(obj["nominal"]) == 5 and len(obj["perturbations"]) == 8
    assert set(obj["all_paths"]) == set(ARMS)
    for key in ("tracking_plot", "robustness_plot"):
        assert (tmp_path / "plots" / obj["outputs"][key].split("/")[-1]).stat().st_size > 10_000


def test_cli_compensate_table_and_help(tmp_path, capsys):
    path = tmp_path / "model.json"
    path.write_text(ModelFile(model=PAPER_PLANT, output_unit="rad", band=0.03).to_json())
    assert main(["compensate", str(path), "--no-plots", "--samples", "240", "--plant", "paper"]) == 0
    out = capsys.readouterr().out
    for word in ("encoder resolution q = 0.0075 rad", "all paths", "robustness", "+20%", "nominal"):
        assert word in out
    with pytest.raises(SystemExit):
        main(["compensate", "--help"])
    help_text = capsys.readouterr().out
    for word in ("--plant", "--resolution", "--band", "--integral-gain", "dead time", "ZPETC", "examples"):
        assert word in help_text
