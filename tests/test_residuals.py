"""Regime breakdown and resid-style checks on residuals whose structure is known."""

import numpy as np
import pytest

from servoid.errors import ConfigError
from servoid.ident.diagnosis.residuals import GROUPS, regime_breakdown, residual_tests, where_text


def triangle(n=2000, period=100):
    k = np.arange(n)
    return np.abs((k % period) - period / 2)  # reversals every period/2 samples


def test_shares_partition_the_record_in_every_group():
    rng = np.random.default_rng(0)
    motion = triangle()
    y_hat = rng.normal(size=motion.size)
    y = y_hat + rng.normal(size=motion.size)
    b = regime_breakdown(y, y_hat, rng.uniform(-1, 1, motion.size), motion)
    for group in GROUPS:
        regimes = b.group(group)
        assert sum(r.sample_share for r in regimes) == pytest.approx(1.0)
        assert sum(r.energy_share for r in regimes) == pytest.approx(1.0)


def test_error_after_reversals_is_found_and_said_in_words():
    rng = np.random.default_rng(1)
    motion = triangle()
    r = 0.01 * rng.normal(size=motion.size)
    reversal = np.flatnonzero(np.diff(np.sign(np.diff(motion, prepend=motion[0]))) != 0) + 1
    for k in reversal:
        r[k : k + 5] += 1.0  # the model misses something for 5 samples after each reversal
    y = 10 * np.sin(np.arange(motion.size) / 30)
    b = regime_breakdown(y, y - r, np.ones(motion.size), motion, reversal_window=5)
    after = [x for x in b.group("reversal") if x.label.startswith("within")][0]
    assert after.sample_share == pytest.approx(0.1, abs=0.01)
    assert after.energy_share > 0.95
    text = where_text(b)
    assert text.startswith(
        f"{100 * after.energy_share:.0f} % of the error energy lies within 5 samples after a reversal"
    )


def test_amplitude_bands_use_the_lagged_input():
    rng = np.random.default_rng(2)
    u = rng.uniform(-1, 1, 4000)
    r = np.zeros(u.size)
    r[3:] = np.where(np.abs(u[:-3]) < 0.25, 1.0, 0.0)  # error where |u(k-3)| is small
    b = regime_breakdown(
        r + 1e-3 * rng.normal(size=u.size) + np.arange(u.size),
        np.arange(u.size, dtype=float),
        u,
        np.cumsum(u),
        input_lag=3,
    )
    low = b.group("input amplitude")[0]
    assert low.label.startswith("|u(k-3)| in [") and low.energy_share > 0.95


def test_white_residual_passes_and_structure_fails():
    rng = np.random.default_rng(3)
    u = rng.normal(size=5000)
    white = residual_tests(rng.normal(size=5000), u)
    assert white.white and white.independent_of_input
    coloured = residual_tests(np.convolve(rng.normal(size=5000), np.ones(5), mode="same"), u)
    assert not coloured.white
    dependent = residual_tests(np.r_[np.zeros(3), 0.5 * u[:-3]] + rng.normal(size=5000), u)
    assert not dependent.independent_of_input
    assert abs(dependent.cross_correlation[3]) > dependent.band and dependent.band == pytest.approx(
        2.576 / np.sqrt(5000), rel=1e-3
    )


def test_bad_arguments_are_named():
    with pytest.raises(ConfigError, match="same length"):
        regime_breakdown(np.ones(10), np.ones(9), np.ones(10), np.ones(10))
    with pytest.raises(ConfigError, match="too few"):
        residual_tests(np.ones(20), np.ones(20), max_lag=25)
