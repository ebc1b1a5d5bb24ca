"""Pseudo-random binary sequences: maximum-length sequences held ``hold`` samples per bit.

A maximum-length sequence of a ``order``-bit shift register repeats every
``L = 2^order - 1`` bits and its circular autocorrelation over one period is
an impulse (``L`` at lag 0, ``-1`` elsewhere, for ``+-1`` values): its
spectrum is flat, the property that makes it a standard identification input.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.signal import max_len_seq

from servoid.excitation.specs import PRBSSpec
from servoid.excitation.streams import doubles

__all__ = ["prbs", "mls"]


@lru_cache(maxsize=8)
def mls(order: int) -> np.ndarray:
    """One period of the maximum-length sequence of ``order`` bits as ``+-1`` (read-only)."""
    bits = max_len_seq(order)[0]
    seq = 2.0 * bits.astype(np.float64) - 1.0
    seq.flags.writeable = False
    out: np.ndarray = seq
    return out


def prbs(spec: PRBSSpec, seed: int, start: int, count: int) -> np.ndarray:
    """``offset +- amplitude`` following the sequence, from a phase the seed picks.

    Every non-zero start state of the register gives a cyclic shift of the
    same sequence, so the seed only picks the shift.
    """
    seq = mls(spec.order)
    phase = int(doubles(seed, 0, 0, 1)[0] * seq.size)
    bit = (np.arange(start, start + count) // spec.hold + phase) % seq.size
    return spec.offset + spec.amplitude * seq[bit]
