"""The Diebold-Mariano statistic of two places' validation errors (:mod:`servoid.ident.offline.place_test`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from servoid.ident.offline.place_test import place_z


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
