"""Random numbers addressed by position, so that a signal can resume anywhere.

Every random kind draws its numbers from :func:`doubles`: the ``count``
doubles of stream ``stream`` of ``seed`` that start at position ``start``.
The answer depends only on those four numbers, never on what was drawn
before, which is what makes the generators pure and chunked output equal
one-shot output. Each double costs one 64-bit draw of PCG64, so jumping to a
position is :meth:`numpy.random.PCG64.advance`, O(log start).

Stream 0 of a seed is exactly ``numpy.random.default_rng(seed)``: the
paper's input ``default_rng(seed).uniform(-A, A, n)`` is the ``uniform``
kind with that seed.
"""

from __future__ import annotations

import numpy as np

from servoid import validation

__all__ = ["doubles", "check_seed"]


def check_seed(seed: object) -> int:
    """Return ``seed`` as an int ``>= 0`` or raise :class:`~servoid.errors.ConfigError` naming it."""
    return validation.integer("seed", seed, minimum=0)


def doubles(seed: int, stream: int, start: int, count: int) -> np.ndarray:
    """Doubles in ``[0, 1)`` number ``start .. start + count - 1`` of stream ``stream`` of ``seed``.

    Parameters
    ----------
    seed : int
        The user's seed, ``>= 0``.
    stream : int
        Independent stream of that seed (0 is ``default_rng(seed)`` itself;
        others are spawned children of its seed sequence).
    start, count : int
        Position of the first double and how many.
    """
    seq = np.random.SeedSequence(seed, spawn_key=(stream,) if stream else ())
    bits = np.random.PCG64(seq)
    if start:
        bits.advance(start)
    return np.random.Generator(bits).random(count)
