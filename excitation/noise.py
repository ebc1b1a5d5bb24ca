"""Random signals: uniform white noise, random steps, dithered operating levels.

Each function returns the target values ``u(start) .. u(start + count - 1)``
in the unit of ``u`` (before the bound and the rate limit are applied, see
:mod:`servoid.excitation.shaping`) as a pure function of the spec, the seed
and the positions (:func:`servoid.excitation.streams.doubles`).
"""

from __future__ import annotations

import numpy as np

from servoid.excitation.specs import LevelsSpec, StepsSpec, UniformSpec
from servoid.excitation.streams import doubles

__all__ = ["uniform", "steps", "levels"]

# Independent random streams of one seed, one per use.
_STREAM_MAIN = 0
_STREAM_ORDER = 1
_STREAM_DITHER = 2


def _uniform_in(low: float, high: float, r: np.ndarray) -> np.ndarray:
    # NumPy's own formula in Generator.uniform, so that stream 0 reproduces
    # default_rng(seed).uniform(low, high, n) bit for bit.
    return low + (high - low) * r


def _per_block(seed: int, stream: int, start: int, count: int, block: int) -> np.ndarray:
    """One double per block of ``block`` samples, repeated over the samples ``start .. start + count - 1``."""
    first = start // block
    last = (start + count - 1) // block
    r = doubles(seed, stream, first, last - first + 1)
    return r[np.arange(start, start + count) // block - first]


def uniform(spec: UniformSpec, seed: int, start: int, count: int) -> np.ndarray:
    """Uniform white noise on ``[offset - amplitude, offset + amplitude]``, one value per sample."""
    r = doubles(seed, _STREAM_MAIN, start, count)
    values = _uniform_in(-spec.amplitude, spec.amplitude, r)
    return values if spec.offset == 0.0 else values + spec.offset


def steps(spec: StepsSpec, seed: int, start: int, count: int) -> np.ndarray:
    """Random levels held ``hold`` samples each: any value in the bound, or one of ``levels`` evenly spaced."""
    if count == 0:
        return np.empty(0)
    r = _per_block(seed, _STREAM_MAIN, start, count, spec.hold)
    if spec.levels == 0:
        return spec.offset + _uniform_in(-spec.amplitude, spec.amplitude, r)
    index = np.minimum(np.floor(r * spec.levels), spec.levels - 1)
    out: np.ndarray = spec.offset + spec.amplitude * (-1.0 + 2.0 * index / (spec.levels - 1))
    return out


def levels(spec: LevelsSpec, seed: int, start: int, count: int) -> np.ndarray:
    """Dwell at each operating level in turn, ``dither`` around it.

    The levels are visited in cycles of ``count`` visits, each cycle a random
    permutation (so every level is visited once per cycle), and each visit
    lasts ``dwell`` samples. The dither is uniform, held ``hold`` samples.
    """
    if count == 0:
        return np.empty(0)
    centres = np.asarray(spec.centres)
    k = np.arange(start, start + count)
    visit = k // spec.dwell
    cycle = visit // spec.count
    first, last = int(cycle[0]), int(cycle[-1])
    # A permutation per cycle from `count` doubles at the cycle's position of
    # the stream: pure in (seed, cycle), hence resumable.
    keys = doubles(seed, _STREAM_ORDER, first * spec.count, (last - first + 1) * spec.count)
    perms = np.argsort(keys.reshape(-1, spec.count), axis=1, kind="stable")
    level = centres[perms[cycle - first, visit % spec.count]]
    dither = spec.dither or 0.0
    if dither == 0.0:
        return level
    r = _per_block(seed, _STREAM_DITHER, start, count, spec.hold)
    out: np.ndarray = level + _uniform_in(-dither, dither, r)
    return out
