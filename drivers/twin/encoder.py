"""Encoders: an angle becomes whole counts, with optional noise, as the drive samples it.

Convention: an encoder with ``cpr`` counts per revolution of its shaft reads
``floor(theta * cpr / (2 pi) + 1/2 + noise)``: the count whose interval is
centred on the angle (the encoder's zero is set to the middle of count 0,
as a homing offset does), so the quantisation error is uniform in
``[-1/2, 1/2)`` count and unbiased. ``noise`` is a standard normal draw
times the encoder's noise level in counts, drawn when the drive samples the
encoder (one draw per sample, from the twin's seeded generator); it stands
for the transition noise of a magnetic or optical encoder near a count
boundary. Counts are signed and unbounded (multi-turn); the wrap of a
single-turn register (0..4095) is the protocol's business.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np

from servoid.drivers.twin._jit import jit

T = TypeVar("T", float, np.ndarray)

__all__ = ["quantise", "counts_to_rad", "rad_per_count"]

_TWO_PI = 2.0 * math.pi


@jit
def quantise(theta: float, cpr: float, noise_counts: float) -> float:
    """The count an encoder of ``cpr`` counts per revolution reads at ``theta`` rad.

    Parameters
    ----------
    theta : float
        Shaft angle, rad.
    cpr : float
        Counts per revolution (> 0).
    noise_counts : float
        Noise added before quantisation, counts (0 for none).

    Returns
    -------
    float
        The count, a whole number (float so that the compiled kernels need no casts).
    """
    return math.floor(theta * cpr / _TWO_PI + 0.5 + noise_counts)


def rad_per_count(cpr: float) -> float:
    """Angle of one count, rad."""
    return _TWO_PI / cpr


def counts_to_rad(counts: T, cpr: float) -> T:
    """The nominal angle of a count (or an array of counts), rad."""
    return counts * _TWO_PI / cpr
