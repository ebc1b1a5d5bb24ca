"""Deterministic periodic signals: multisine with Schroeder phases, and the chirp.

Both are pure functions of the sample index, so the seed is not used and any
chunk equals the same slice of a one-shot run.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from servoid.excitation.specs import ChirpSpec, MultisineSpec

__all__ = ["multisine", "chirp", "schroeder_phases", "multisine_period", "crest_factor"]


def schroeder_phases(lines: int) -> np.ndarray:
    """Schroeder's phases ``phi_l = -pi l (l - 1) / K`` for ``K`` equal-amplitude lines, ``l = 1..K``.

    Notes
    -----
    M. R. Schroeder, "Synthesis of low-peak-factor signals and binary
    sequences with low autocorrelation", IEEE Trans. Inf. Theory 16 (1970):
    with these phases a flat-spectrum multisine has a crest factor near
    ``sqrt(2)``, against ``sqrt(2 K)`` when all phases are equal.
    """
    idx = np.arange(1, lines + 1, dtype=np.float64)
    return -np.pi * idx * (idx - 1.0) / lines


def crest_factor(values: np.ndarray) -> float:
    """Peak over RMS, ``max |v| / sqrt(mean(v^2))``, of a zero-mean signal ``v``."""
    v = np.asarray(values, dtype=np.float64)
    rms = float(np.sqrt(np.mean(v * v)))
    return float(np.max(np.abs(v))) / rms if rms > 0.0 else math.inf


@lru_cache(maxsize=16)
def multisine_period(period: int, harmonics: tuple[int, ...]) -> np.ndarray:
    """One period of the unit-peak multisine on ``harmonics`` (read-only).

    ``sum_l cos(2 pi l k / period + phi_l)`` with Schroeder phases, divided by
    its largest magnitude over the period, so that its peak is exactly 1.
    """
    k = np.arange(period, dtype=np.float64)
    phases = schroeder_phases(len(harmonics))
    table = np.zeros(period)
    for line, phase in zip(harmonics, phases):
        # (line * k) mod period keeps the argument small and exact for large k
        table += np.cos(2.0 * np.pi * ((line * k) % period) / period + phase)
    table /= np.max(np.abs(table))
    table.flags.writeable = False
    return table


def multisine(spec: MultisineSpec, seed: int, start: int, count: int) -> np.ndarray:
    """The multisine of ``spec``, peak ``amplitude`` around ``offset``."""
    table = multisine_period(spec.period, spec.harmonics)
    return spec.offset + spec.amplitude * table[np.arange(start, start + count) % spec.period]


def _cycles(spec: ChirpSpec, t: np.ndarray) -> np.ndarray:
    """Cycles completed ``t`` samples into a sweep: the integral of the instantaneous frequency."""
    f0, f1, length = spec.f0, spec.f1, float(spec.period)
    if spec.sweep == "log" and f0 != f1:
        ratio = f1 / f0
        return f0 * length / math.log(ratio) * (ratio ** (t / length) - 1.0)
    out: np.ndarray = f0 * t + (f1 - f0) * t * t / (2.0 * length)
    return out


def chirp(spec: ChirpSpec, seed: int, start: int, count: int) -> np.ndarray:
    """``offset + amplitude sin(2 pi cycles(k))``, sweeping ``f0 -> f1`` every ``period`` samples.

    The phase runs on across sweeps (no jump at the restart), and the signal
    starts at ``offset`` with a rising slope.
    """
    k = np.arange(start, start + count)
    sweep, t = np.divmod(k, spec.period)
    per_sweep = float(_cycles(spec, np.array([float(spec.period)]))[0]) % 1.0
    cycles = (sweep * per_sweep) % 1.0 + _cycles(spec, t.astype(np.float64))
    out: np.ndarray = spec.offset + spec.amplitude * np.sin(2.0 * np.pi * (cycles % 1.0))
    return out
