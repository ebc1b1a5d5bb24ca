"""Gentle sines: the excitation that shows a play inside the position loop (the issue-12 study, Q3).

A servo whose encoder sits on the load (a Dynamixel's or Feetech's horn)
closes its loop around the play. At each reversal the load should wait on the
trailing flank while the motor crosses the whole play: that dead time is all
the data say about the play. If the set point decelerates harder than the
load's own friction can, the load coasts across the play by itself and stops
on the leading flank, and the play vanishes from the record (held steps and
white set points do that). Gentle sines keep the peak acceleration low:

segment j = ``cycles`` periods of ``offset + a_j sin(2 pi f_j t)``, with ``a_j``
log-uniform in ``[smallest amplitude, amplitude]`` and the peak acceleration
``a_j (2 pi f_j)^2`` log-uniform in ``[accel / spread, accel]`` (unit per
sample squared), so ``f_j = sqrt(acc_j / a_j) / (2 pi)`` cycles per sample
(at most 0.25).

Pure and resumable: segment ``j`` draws its two numbers at positions ``2 j``
and ``2 j + 1`` of stream 0 of the seed (:func:`~servoid.excitation.streams.doubles`),
so any chunk equals the same slice of a one-shot run.
"""

from __future__ import annotations

import math

import numpy as np

from servoid.excitation.specs import GentleSpec
from servoid.excitation.streams import doubles

__all__ = ["gentle", "segment_end", "segments", "whole_segments"]

#: Segments drawn per look-up batch while walking to a start index.
_BATCH = 256
#: Highest frequency of a segment, cycles per sample (4 samples per period).
_F_MAX = 0.25


def segments(spec: GentleSpec, seed: int, first: int, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Amplitude, frequency (cycles per sample) and length (samples) of segments ``first .. first + count - 1``.

    Parameters
    ----------
    spec : GentleSpec
        The signal.
    seed : int
        Its seed.
    first, count : int
        Which segments.

    Returns
    -------
    amplitude, frequency, length : ndarray
    """
    d = doubles(seed, 0, 2 * first, 2 * count).reshape(count, 2)
    amp = spec.amplitude * np.exp(np.log(spec.smallest) * (1.0 - d[:, 0]))
    acc = spec.accel * np.exp(-np.log(spec.spread) * d[:, 1])
    freq = np.minimum(np.sqrt(acc / amp) / (2.0 * np.pi), _F_MAX)
    length = np.maximum(4, np.floor(spec.cycles / freq)).astype(np.int64)
    return amp, freq, length


def gentle(spec: GentleSpec, seed: int, start: int, count: int) -> np.ndarray:
    """Samples ``start .. start + count - 1`` of the gentle sines of ``spec`` (target values, before the bound).

    Parameters
    ----------
    spec : GentleSpec
        The signal.
    seed : int
        Its seed.
    start, count : int
        The first sample and how many.

    Returns
    -------
    ndarray
    """
    out = np.empty(count)
    j = 0
    begin = 0  # index of segment j's first sample
    filled = 0
    while filled < count:
        amp, freq, length = segments(spec, seed, j, _BATCH)
        ends = begin + np.cumsum(length)
        for i in range(_BATCH):
            end = int(ends[i])
            seg_begin = end - int(length[i])
            lo = max(start + filled, seg_begin)
            if end > lo:
                take = min(end, start + count) - lo
                t = np.arange(lo - seg_begin, lo - seg_begin + take, dtype=np.float64)
                out[filled : filled + take] = spec.offset + amp[i] * np.sin(2.0 * math.pi * freq[i] * t)
                filled += take
                if filled >= count:
                    break
        j += _BATCH
        begin = int(ends[-1])
    return out


def whole_segments(spec: GentleSpec, seed: int, limit: int) -> int:
    """The samples of the whole segments that fit in the first ``limit`` (0 when the first segment does not).

    A run cut there ends a segment back at its offset (each segment is whole periods of a sine), so
    another signal may follow without a step.

    Parameters
    ----------
    spec : GentleSpec
        The signal.
    seed : int
        Its seed.
    limit : int
        The most samples.

    Returns
    -------
    int
    """
    return _boundaries(spec, seed, limit)[0]


def segment_end(spec: GentleSpec, seed: int, index: int) -> int:
    """The end of the segment that holds sample ``index`` (``index`` itself when a segment starts there).

    A signal that follows from there starts where the gentle sines are back at their offset (each
    segment is whole periods of a sine): no step in the command (:func:`whole_segments` cuts before
    a limit, this one after an index).

    Parameters
    ----------
    spec : GentleSpec
        The signal.
    seed : int
        Its seed.
    index : int
        A sample index, 0 or more.

    Returns
    -------
    int
    """
    return _boundaries(spec, seed, index)[1]


def _boundaries(spec: GentleSpec, seed: int, index: int) -> tuple[int, int]:
    """The last segment boundary at or before sample ``index`` and the first at or after it (0 is one)."""
    begin, j = 0, 0
    while True:
        ends = begin + np.cumsum(segments(spec, seed, j, _BATCH)[2])
        if ends[-1] >= index:
            bounds = np.concatenate(([begin], ends))
            return int(bounds[bounds <= index][-1]), int(bounds[bounds >= index][0])
        begin, j = int(ends[-1]), j + _BATCH
