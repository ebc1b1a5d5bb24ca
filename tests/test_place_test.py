"""The place tests of two places' validation errors: the Diebold-Mariano statistic, the catch-ups after reversals (:mod:`servoid.ident.offline.place_test`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from servoid.drivers.twin import Twin, preset
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.offline.loop_fit import block_mask
from servoid.ident.offline.place_test import catch_up_groups, place_z, reversal_z


def _correlated(rng: np.random.Generator, n: int) -> np.ndarray:
    """Errors correlated over tens of samples, as a free run's are (AR(1), pole 0.95)."""
    return lfilter([1.0], [1.0, -0.95], rng.normal(0.0, 1.0, n))


def test_equal_models_score_near_zero_and_a_better_one_scores_high() -> None:
    rng = np.random.default_rng(3)
    n = 4000
    # two models alike: the statistic is a standard normal over repeats (rarely beyond 3)
    zs = [place_z(_correlated(rng, n), _correlated(rng, n)) for _ in range(40)]
    assert abs(float(np.mean(zs))) < 0.6 and float(np.std(zs)) < 1.6
    assert sum(abs(z) > 3.0 for z in zs) <= 2
    # the other model's error 10 % larger everywhere: the winner's place, surely; swapped, the other sign
    common = _correlated(rng, n)
    better = place_z(common + 0.1 * _correlated(rng, n), 1.1 * common + 0.1 * _correlated(rng, n))
    assert better > 3.0
    assert place_z(1.1 * common, common) < -3.0


def test_the_correlation_widens_the_error_of_the_mean() -> None:
    # the same loss differential's statistic, white against correlated: the long-run variance counts the
    # correlated samples as fewer (naive i.i.d. z would be several times larger)
    rng = np.random.default_rng(4)
    n = 4000
    a, b = _correlated(rng, n), _correlated(rng, n)
    d = b * b - a * a
    naive = float(np.mean(d)) / (float(np.std(d)) / math.sqrt(n))
    assert abs(place_z(a, b)) < abs(naive)


def test_degenerate_input_gives_nan_or_infinity() -> None:
    assert math.isnan(place_z(np.zeros(1), np.zeros(1)))
    assert math.isnan(place_z(np.array([1.0, np.nan]), np.ones(2)))
    assert math.isnan(place_z(np.ones(3), np.ones(4)))
    assert math.isnan(place_z(np.ones(5), np.ones(5)))
    assert place_z(np.ones(5), 2.0 * np.ones(5)) == math.inf


def _xm430(u: np.ndarray, period: float, noise_counts: float, **over: object) -> tuple[np.ndarray, float]:
    """The XM430 twin's readings of ``u`` (4096-count horn encoder) and its play; ``over``: twin fields."""
    twin = Twin(preset("xm430", load_encoder_cpr=4096, encoder_noise_counts=noise_counts, **over), seed=5)
    twin.enable()
    return np.asarray(twin.sample(u, period).y, dtype=np.float64), twin.truth.play_rad


def test_the_catch_ups_after_reversals_name_the_place_and_ignore_the_strokes_between() -> None:
    # 10 s of gentle sines at 20x the XM430's loop bandwidth (the play in the loop, 2.8 counts): its own
    # noise-free response (the right place) against the same servo's with the loop closed on the motor
    period = 1.0 / 70.0
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 * period**2, spread=8.0), 700, seed=5)
    y, play = _xm430(u, period, 0.3)
    right, _ = _xm430(u, period, 0.0)
    wrong, _ = _xm430(u, period, 0.0, loop_encoder="motor", motor_encoder_cpr=2**22)
    val = ~block_mask(u.size)
    groups = catch_up_groups(right, play, 2, val)
    assert len(groups) >= 10 and all(val[g].all() for g in groups)
    assert reversal_z(right - y, wrong - y, groups) > 3.0
    assert reversal_z(wrong - y, right - y, groups) < -3.0
    # the right place's fit off by two counts between the catch-ups (what a fit trades mid-stroke): the
    # whole-record statistic turns against it, the catch-ups' does not move
    between = np.ones(u.size, dtype=bool)
    for g in groups:
        between[g] = False
    traded = right + np.where(between, 2.0 * 2.0 * math.pi / 4096, 0.0)
    assert place_z((traded - y)[val], (wrong - y)[val]) < place_z((right - y)[val], (wrong - y)[val])
    assert reversal_z(traded - y, wrong - y, groups) == reversal_z(right - y, wrong - y, groups)


def test_reversal_z_needs_three_reversals_and_finite_errors() -> None:
    e = np.ones(10)
    groups = [np.array([0, 1]), np.array([4]), np.array([7, 8])]
    assert math.isnan(reversal_z(e, 2.0 * e, groups[:2]))
    assert reversal_z(e, 2.0 * e, [np.array([0]), np.array([4]), np.array([7])]) == math.inf
    assert math.isnan(reversal_z(e, np.where(np.arange(10) == 4, np.nan, 1.0), groups))
    assert math.isnan(reversal_z(e, np.ones(9), groups))
