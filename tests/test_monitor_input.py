"""The monitor's steady sine with its amplitude dithered over the loop encoder's count grid (``monitor_spec(dither=)``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid.excitation.generate import sample
from servoid.excitation.gentle import segments
from servoid.excitation.monitor_input import SINE, monitor_spec


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
