"""The monitor's steady sine with its amplitude dithered over the loop encoder's count grid (``monitor_spec(dither=)``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid.excitation.generate import sample
from servoid.excitation.gentle import segments
from servoid.excitation.monitor_input import SINE, cycled_sine, monitor_spec


def test_no_dither_is_the_steady_sine_as_before() -> None:
    spec = monitor_spec(SINE, 0.1, 1e-4)
    assert (spec.smallest, spec.spread, spec.cycles) == (1.0, 1.0, 3)
    assert monitor_spec(SINE, 0.1, 1e-4, dither=0.0) == spec


def test_dither_draws_each_period_its_own_amplitude_at_the_same_acceleration() -> None:
    accel = 4.0 / 200.0**2
    spec = monitor_spec(SINE, 0.1, 2.0 * accel, dither=0.05)  # the sine's peak: half the identification's
    amp, freq, length = segments(spec, 7, 0, 40)
    assert spec.cycles == 1
    assert np.all(amp <= 0.1 + 1e-12) and np.all(amp >= 0.095 - 1e-12)
    assert np.ptp(amp) > 0.02 * 0.1  # spread over most of the span: many places on a count grid
    np.testing.assert_allclose(amp * (2.0 * math.pi * freq) ** 2, accel, rtol=1e-9)
    u = sample(spec, int(length.sum()), seed=7)
    assert np.max(np.abs(u)) <= 0.1 + 1e-12


@pytest.mark.parametrize("dither", [-0.1, 0.6, math.nan])
def test_dither_out_of_range_is_refused(dither: float) -> None:
    with pytest.raises(ValueError, match="dither"):
        monitor_spec(SINE, 0.1, 1e-4, dither=dither)


def _reversals(u: np.ndarray) -> np.ndarray:
    """Indices of the local extremes of ``u`` (a reversal of the set point each)."""
    d = np.diff(u)
    return np.flatnonzero(np.sign(d[1:]) != np.sign(d[:-1])) + 1


@pytest.mark.parametrize("steps", [3, 4])
def test_cycled_sine_puts_each_side_on_distinct_places_of_the_grid(steps: int) -> None:
    count = 2.0 * math.pi / 4096.0
    accel = 4.0 / 200.0**2
    spec = monitor_spec(SINE, 0.1, 2.0 * accel, offset=0.3)
    u = cycled_sine(spec, count, steps, 4000)
    assert np.max(np.abs(np.diff(u))) <= math.sqrt(0.1 * accel) * (1.0 + 1e-9)  # no step: the sine's own slope at most
    idx = _reversals(u)
    amp = np.abs(u[idx] - 0.3)
    expected = 0.1 - np.arange(steps) * count / steps
    # every peak sits within the sampling's rounding of one of the cycle's amplitudes, in the cycle's order
    nearest = np.argmin(np.abs(amp[:, None] - expected[None, :]), axis=1)
    np.testing.assert_allclose(amp, expected[nearest], atol=accel)  # a peak sample's rounding: under a w^2 / 8
    np.testing.assert_array_equal(nearest[: 2 * steps], np.arange(2 * steps) % steps)
    tops = {int(k) for k, v in zip(nearest, u[idx] > 0.3, strict=True) if v}
    # odd steps: both sides pass every place; even: each side half of them
    assert len(tops) == (steps if steps % 2 else steps // 2)


def test_cycled_sine_of_one_step_is_the_steady_sine_at_its_peak_acceleration() -> None:
    accel = 4.0 / 200.0**2
    spec = monitor_spec(SINE, 0.1, 2.0 * accel)
    u = cycled_sine(spec, 0.0015, 1, 2000)
    t = np.arange(2000)
    np.testing.assert_allclose(u, 0.1 * np.sin(np.sqrt(accel / 0.1) * t), atol=1e-9)


@pytest.mark.parametrize(("count", "steps"), [(0.0, 3), (0.2, 3), (math.nan, 3), (0.0015, 0)])
def test_cycled_sine_refuses_a_bad_count_or_steps(count: float, steps: int) -> None:
    with pytest.raises(ValueError, match="count|steps"):
        cycled_sine(monitor_spec(SINE, 0.1, 1e-4), count, steps, 10)
