"""The monitor's own input for a play inside the loop: the identification's gentle sines, then one steady sine.

A monitor that follows the play alone (:mod:`servoid.ident.monitoring.loop_wear`)
holds the loop it refitted first, so each window's play carries that loop's
bias, and the bias depends on the segment of gentle sines the window sees
(slow, large, small). One segment kind holds it still, and the baseline takes
it out: after the first fit, one steady sine at the identification's largest
amplitude and :data:`SINE_ACCEL_SHARE` of its highest peak acceleration
(``benchmarks/monitor_loop.py``, docs/monitor.md "steady sine"), and, for a
play outside the loop, at most the acceleration of the design's slow phase,
where the file's play was sized (:func:`coast_accel`). Why not the
highest: the held loop's load is massless, and a set point that reverses at
the top of the identification's range lets a horn coast across part of the
play, so the window plays follow the play less than it grows: on the XM430
twin's data file a +20 % step moved them by +6 % at 8 rad/s^2 (no alarm), by
+19 % at 4 and +22 % at 2 (alarm 1.25 and 1.5 s). Why not lower: a window
must hold :data:`~servoid.ident.monitoring.loop_wear.MIN_REVERSALS` reversals
to count; at 2 rad/s^2 (1.4 reversals a second) 30 % of the XM430's windows
did. The first fit, which refits the whole loop, keeps the identification's
sines: their segments of many amplitudes and accelerations are what the
loop's parameters need.

Where the play sits inside the loop the servo's firmware closes its loop on whole counts of the horn's
encoder (the twins' XM430 and STS3215: the play is 2.8 and 6.8 counts), a term the continuous servo-loop
model does not carry. A steady sine reverses at the same place on that count grid every period, and the
held loop reads the play there with a bias of its own: on the XM430 twin's file the window plays read
0.90x the play the monitor's first fit reads on the identification's sines, and 0.94 / 1.09 / 0.89 /
0.94x with the sine's amplitude a quarter count larger each time (the STS3215's: 0.94 / 0.97 / 1.02 /
1.04x); with the loop closed on 16x finer counts 0.96-1.00x (docs/monitor.md, "the count grid"). The
identification's sines reverse at many places and average it out. ``dither`` (off by default) draws the
steady sine's amplitude anew each period within ``[(1 - dither) A, A]``: its reversals then spread over
the grid, at the price of window plays that scatter with it. :func:`cycled_sine` (off by default) steps it
instead, deterministically: each half-period ``count / steps`` smaller, over ``steps`` values, so that every
reversal side passes the same ``steps`` places on the grid (``count``: the loop encoder's, from the readings).

Which steady sine runs (:data:`STEADY` or :data:`CYCLED`, ``servoid monitor --input``): the steady one by default.
The cycled one, over :data:`CYCLE_STEPS` places, is meant for a play inside the loop and is the default there only
with :data:`CYCLED_DEFAULT` (off: on the twins' live files it delayed the XM430's alarm; :func:`default_input`). The
count grid is a property of a loop closed on the encoder the readings come from:
the horn servos' firmware (XM430, STS3215) closes its position loop on whole counts of the horn's encoder, so the
readings' count is the loop's grid, and the cycle moves each reversal by a known share of it (on the XM430 twin's
data file the window plays read 4.6 % low instead of 9.0-9.3 %, the STS3215's 3.9-4.0 % instead of 7.2-7.3 %, the
alarm after +20 % within 0.75-2.00 s; on the XM430's live file the alarm came 4.25 s after, against 1.25 s on the
steady sine; docs/monitor.md, mongrid20 and moncycle21). Where the play sits outside the
loop (the CiA 402 and ODrive: the loop closes on the motor's encoder, the readings are the load's, 2^20 and 2^14
counts a turn on the twins), a step of the readings' count moves the reversals by nothing the motor's loop sees:
there the steady sine stays, bit for bit. The count is taken when the steady part starts, from the readings the
monitor's first fit has just used (:func:`grid_count`: no second experiment, no value typed in); where they show
none (too few changes, a continuous or noisy encoder) the steady sine runs instead, and the monitor says why.

The benchmark and ``servoid monitor`` build both parts here (one owner).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from servoid.excitation.generate import stream
from servoid.excitation.gentle import segment_end
from servoid.excitation.monitor_input_names import CYCLE_STEPS, CYCLED, CYCLED_DEFAULT, INPUTS, STEADY
from servoid.excitation.shaping import clip_and_limit
from servoid.excitation.specs import GentleSpec

__all__ = ["CYCLE_STEPS", "CYCLED", "CYCLED_DEFAULT", "IDENT", "INPUTS", "MAX_COUNT_SHARE", "MAX_DITHER", "MIN_COUNT_CHANGES",
           "MONITOR_INPUTS", "SINE", "SINE_ACCEL_SHARE", "STEADY", "EVEN_PHASES", "WHOLE_HALVES", "GridCount", "coast_accel", "cycled_sine",
           "default_input", "grid_count", "half_periods", "monitor_spec", "monitor_stream"]  # fmt: skip

#: The identification's gentle sines (segments of many amplitudes and accelerations).
IDENT = "ident"
#: One steady sine: every segment at the highest amplitude and acceleration.
SINE = "sine"

#: The steady sine's peak acceleration over the identification's highest (the module's text).
SINE_ACCEL_SHARE = 0.5
#: Each input by name: (amplitude over the identification's, spread, smallest, peak acceleration over the
#: identification's highest) of gentle sines. ``ident``: the identification's own (``GentleSpec``'s defaults);
#: ``sine``: one amplitude at :data:`SINE_ACCEL_SHARE` of the highest acceleration, a steady sine.
MONITOR_INPUTS = {IDENT: (1.0, 8.0, 0.25, 1.0), SINE: (1.0, 1.0, 1.0, SINE_ACCEL_SHARE)}
#: Largest ``dither`` of the steady sine's amplitude (:func:`monitor_spec`).
MAX_DITHER = 0.5

#: Fewest changes of the readings :func:`grid_count` takes a count from (those of
#: :func:`~servoid.ident.offline.intervals.quantum`).
MIN_COUNT_CHANGES = 10
#: Largest count over the steady sine's amplitude :func:`grid_count` accepts: the cycle lowers the amplitude by up to
#: ``(steps - 1) / steps`` of a count, here at most 7.5 % (the horn twins: 1 / 65 of it); a coarser "count" is a
#: servo that hardly moved, not an encoder's.
MAX_COUNT_SHARE = 0.1
#: Whether each half-period of :func:`cycled_sine` lasts a whole number of samples (its length rounded up, its peak
#: acceleration lowered to fit: by under 3 % on the twins' 80-100 sample half-periods); off. The set point is sampled,
#: and the horn servos' goal is a whole count: with half-periods of fractional length each peak falls at another place
#: between two samples, which slides from cycle to cycle, so the samples the goal spends on its top count change
#: slowly, and the window plays beat with them. On the XM430 twin's live files that beat (about 3 cycles, 4.4 s)
#: correlated the window plays over 4 estimates (tau 3.1-3.8, h 11.6-13.3): the alarm after +20 % came 3.25-4.25 s
#: late; with whole half-periods 1.50 s (tau 1.0). But the slide is also what averages the level: on the XM430's data
#: file the tracking went from 4.6 to 6.2-6.3 % and the live files read 0.02-0.04x lower (docs/monitor.md, moncyc22).
WHOLE_HALVES = False
#: Sample phases the peaks of :func:`cycled_sine` pass evenly, ``M`` (0: off, the lengths the peak acceleration or
#: :data:`WHOLE_HALVES` gives). Every half-period lasts ``s / M`` samples past a whole number of the same parity
#: (:func:`half_periods`), so consecutive peaks fall ``s / M`` of a sample further each time: any ``M`` in a row pass
#: ``M`` evenly spaced places between two samples, and the sampled pattern repeats exactly after ``lcm(steps, 2, M)``
#: half-periods; with ``M`` coprime to the cycle's steps every amplitude passes all ``M`` places (docs/monitor.md,
#: monphase22). Off.
EVEN_PHASES = 0


def monitor_spec(
    kind: str,
    amplitude: float,
    accel: float,
    *,
    offset: float = 0.0,
    rate: float = math.inf,
    coast: float = math.inf,
    dither: float = 0.0,
) -> GentleSpec:
    """The gentle-sines spec of one monitoring input (:data:`MONITOR_INPUTS`).

    Parameters
    ----------
    kind : str
        ``"ident"`` or ``"sine"``.
    amplitude : float
        The identification's largest amplitude, unit of ``u``.
    accel : float
        The identification's highest peak acceleration, unit of ``u`` per sample squared (at the
        monitor's own sample period).
    offset : float
        The centre, unit of ``u``.
    rate : float
        The servo's largest step per sample (the rate limit), unit of ``u``.
    coast : float
        The steady sine's highest peak acceleration, unit of ``u`` per sample squared: above it the
        load coasts across the play (:func:`coast_accel`). Where it is below the sine's own, the sine
        keeps its frequency (its reversals a second, what a window counts) and its amplitude shrinks
        in proportion.
    dither : float
        The steady sine's amplitude drawn anew each period, log-uniform in ``[(1 - dither) A, A]`` at the
        same peak acceleration, so that its reversals spread over the loop encoder's count grid (the
        module's text); in ``[0, 0.5]``, 0 (default): one amplitude, segments of three periods.

    Returns
    -------
    GentleSpec
    """
    if not 0.0 <= dither <= MAX_DITHER:
        raise ValueError(f"dither must lie in [0, {MAX_DITHER:g}], not {dither!r}")
    scale, spread, smallest, share = MONITOR_INPUTS[kind]
    amp, peak = scale * amplitude, share * accel
    if kind == SINE and coast < peak:  # the same reversals a second, a smaller amplitude: the load does not coast
        amp, peak = amp * coast / peak, coast
    if kind == SINE and dither > 0.0:  # one period a segment, each its own amplitude
        return GentleSpec(amplitude=amp, accel=peak, spread=spread, smallest=1.0 - dither, cycles=1, offset=offset,
                          rate=rate)  # fmt: skip
    return GentleSpec(amplitude=amp, accel=peak, spread=spread, smallest=smallest, offset=offset, rate=rate)


def coast_accel(structure: str, slow_accel: float) -> float:
    """The steady sine's highest peak acceleration from the model file: the slow phase's where the play is outside the loop.

    A play outside the loop (the loop reads the motor; the CiA 402 and ODrive twins) is sized by
    live identification on the design's slow phase, whose decelerations stay below the load's
    friction's (``probe_design.SLOW_SHARE``): the fast phase, and a steady sine at half its
    acceleration, let the load coast across part of the play at each reversal, and the window plays
    then follow the play by less than it grows (the CiA 402 twin's live file: +11 % of a +20 % step,
    no alarm in 20 s; at the slow phase's acceleration +15 %, the alarm 1.25 s after it; docs/monitor.md).
    The load's friction is not measured (the probe cannot; the file's load model put the CiA 402's
    at 112 rad/s^2, the twin's is 10), so the slow phase's acceleration, where the file's play was
    measured, is the bound. A play inside the loop reads the load and keeps :data:`SINE_ACCEL_SHARE`.

    Parameters
    ----------
    structure : str
        Where the model file's play sits (``play_in_loop`` or ``output_backlash``).
    slow_accel : float
        The design's slow phase's highest peak acceleration, in any unit (0 or NaN: none).

    Returns
    -------
    float
        ``slow_accel``, or ``inf`` (no bound) for a play inside the loop or without a slow phase.
    """
    from servoid.ident.models.structure_names import PLAY_IN_LOOP

    if structure == PLAY_IN_LOOP or not (math.isfinite(slow_accel) and slow_accel > 0.0):
        return math.inf
    return float(slow_accel)


def default_input(structure: str, cycled: bool | None = None) -> str:
    """The steady sine's kind by the model file's place of the play: :data:`CYCLED` inside the loop when ``cycled``, else
    :data:`STEADY`.

    The count grid is the loop encoder's, and the readings show it only where the loop closes on the encoder
    they come from: the play inside the loop (the module's text). Outside it the steady sine stays whatever ``cycled``.

    Parameters
    ----------
    structure : str
        Where the model file's play sits (``play_in_loop`` or ``output_backlash``).
    cycled : bool, optional
        Whether the cycled sine is the default inside the loop (default: :data:`CYCLED_DEFAULT`, off).

    Returns
    -------
    str
    """
    from servoid.ident.models.structure_names import PLAY_IN_LOOP

    on = CYCLED_DEFAULT if cycled is None else cycled
    return CYCLED if on and structure == PLAY_IN_LOOP else STEADY


@dataclass(frozen=True)
class GridCount:
    """The loop encoder's count as :func:`grid_count` took it from the readings, or why it could not.

    Attributes
    ----------
    count : float
        The count, unit of the readings; NaN when none was found.
    readings : int
        Readings it was taken from.
    why : str
        Empty with a count; else why none (the steady sine then runs).
    """

    count: float
    readings: int
    why: str = ""

    @property
    def found(self) -> bool:
        """Whether a count was found."""
        return math.isfinite(self.count) and self.count > 0.0

    def to_dict(self) -> dict[str, float | int | str | None]:
        """For JSON (``--json``'s ``grid``, the ``input`` event): the count (null when none), the readings, why not."""
        return {"count": self.count if self.found else None, "readings": self.readings, "why": self.why or None}


def grid_count(readings: np.ndarray, amplitude: float) -> GridCount:
    """The count of the encoder the readings come from (:func:`~servoid.ident.offline.intervals.quantum`), if any.

    Parameters
    ----------
    readings : ndarray
        The position readings (the first fit's), unit of ``u``.
    amplitude : float
        The steady sine's amplitude: a count above :data:`MAX_COUNT_SHARE` of it is refused.

    Returns
    -------
    GridCount
    """
    from servoid.ident.offline.intervals import quantum

    y = np.asarray(readings, dtype=np.float64)
    y = y[np.isfinite(y)]
    changes = int(np.count_nonzero(np.diff(y))) if y.size > 1 else 0
    if changes < MIN_COUNT_CHANGES:
        return GridCount(math.nan, y.size, f"too few readings to see the encoder's count: {y.size} readings, "
                                           f"{changes} changes of them ({MIN_COUNT_CHANGES} needed)")  # fmt: skip
    count = quantum(y)
    if not count > 0.0:
        return GridCount(math.nan, y.size, f"the {y.size} readings are not whole multiples of one count (a continuous "
                                           "or noisy encoder)")  # fmt: skip
    if count > MAX_COUNT_SHARE * amplitude:
        return GridCount(math.nan, y.size, f"the readings' step {count:.4g} is more than {MAX_COUNT_SHARE:g} of the "
                                           f"sine's amplitude {amplitude:.4g} (the servo hardly moved)")  # fmt: skip
    return GridCount(count, y.size)


def monitor_stream(
    amplitude: float,
    accel: float,
    first: int,
    *,
    seed: int,
    offset: float = 0.0,
    rate: float = math.inf,
    coast: float = math.inf,
    dither: float = 0.0,
    count: Callable[[], float] | None = None,
    steps: int = CYCLE_STEPS,
) -> Iterator[float]:
    """The monitor's endless input: ``first`` samples of the identification's sines, then the steady sine.

    Parameters
    ----------
    amplitude, accel, offset, rate, coast, dither : float
        As :func:`monitor_spec`.
    first : int
        Samples of the identification's sines at least (the first fit's, ``FIRST_FIT_S`` at the session's
        rate); they run on to the end of the segment that holds sample ``first``
        (:func:`~servoid.excitation.gentle.segment_end`), so the steady sine starts at the offset
        where the sines are back at it: no step in the command.
    seed : int
        Seed of the identification's sines (the steady sine draws nothing unless ``dither``: its segments are
        alike).
    count : callable, optional
        The cycled sine (:data:`CYCLED`): called once, when the steady part starts (the readings until then are
        known), it returns the loop encoder's count, unit of ``u``; the steady sine's amplitude then cycles over
        ``steps`` places of it (:func:`cycled_sine`). A count that is NaN or not positive runs the steady sine. None
        (default): the steady sine, the input before.
    steps : int
        Places of the cycle (default :data:`CYCLE_STEPS`).

    Returns
    -------
    iterator of float
    """
    ident = monitor_spec(IDENT, amplitude, accel, offset=offset, rate=rate)
    head = stream(ident, seed=seed, n=segment_end(ident, seed, first))
    steady = monitor_spec(SINE, amplitude, accel, offset=offset, rate=rate, coast=coast, dither=dither)
    if count is None:
        return itertools.chain(head, stream(steady, seed=seed))
    if dither > 0.0:
        raise ValueError("dither and the cycled sine exclude each other")
    return itertools.chain(head, _steady_or_cycled(steady, seed, count, steps))


def _steady_or_cycled(steady: GentleSpec, seed: int, count: Callable[[], float], steps: int,
                      chunk: int = 4096) -> Iterator[float]:  # fmt: skip
    """The cycled sine over ``count()``'s grid, taken when the first value is asked for; the steady sine without it."""
    grid = count()
    if not (math.isfinite(grid) and 0.0 < grid < float(steady.amplitude)):
        yield from stream(steady, seed=seed)
        return
    start, last = 0, float(steady.offset)
    while True:
        values, last = clip_and_limit(cycled_sine(steady, grid, steps, chunk, start=start), low=steady.low,
                                      high=steady.high, rate=steady.rate, last=last)  # fmt: skip
        yield from values.tolist()
        start += chunk


def half_periods(amps: np.ndarray, accel: float, phases: int) -> np.ndarray:
    """Half-period lengths, samples, at most at the peak acceleration, whose peaks pass ``phases`` sample phases evenly.

    Each length ``pi sqrt(a_k / accel)`` is lengthened to the next value ``s / phases + p`` modulo 2 (``s`` coprime to
    ``phases``, ``p`` 0 or 1, the same for all: the pair that lengthens the longest least), so consecutive peaks lie
    ``(L_k + L_k+1) / 2 = s / phases`` modulo 1 apart: their fractional positions step over ``phases`` evenly spaced
    values (:data:`EVEN_PHASES`). The peak acceleration is lowered to fit (the amplitudes stay).

    Parameters
    ----------
    amps : ndarray
        The half-periods' amplitudes, unit of ``u``.
    accel : float
        The peak acceleration, unit of ``u`` per sample squared.
    phases : int
        Sample phases ``M``, ``>= 2``.

    Returns
    -------
    ndarray
        One length per amplitude, samples.
    """
    if phases < 2:
        raise ValueError(f"phases must be 2 or more, not {phases!r}")
    free = np.pi * np.sqrt(np.asarray(amps, dtype=np.float64) / accel)
    best: np.ndarray | None = None
    for s in range(1, phases):
        if math.gcd(s, phases) != 1:
            continue
        for parity in (0, 1):
            rest = s / phases + parity  # the lengths' value modulo 2
            lengths = rest + 2.0 * np.ceil((free - rest) / 2.0 - 1e-9)
            if best is None or float(np.max(lengths - free)) < float(np.max(best - free)):
                best = lengths
    assert best is not None  # (phases >= 2: s = 1 is coprime)
    return best


def cycled_sine(
    spec: GentleSpec,
    count: float,
    steps: int,
    n: int,
    *,
    start: int = 0,
    whole: bool = WHOLE_HALVES,
    phases: int = EVEN_PHASES,
) -> np.ndarray:
    """``n`` samples of the steady sine ``spec`` whose amplitude cycles over ``steps`` places of a count grid.

    Half-period ``k`` (a reversal each, the sides alternating) has the amplitude ``A - (k mod steps) count / steps``
    and the steady sine's peak acceleration (its length ``pi sqrt(a_k / accel)`` samples; with ``whole`` that
    length rounded up to whole samples and the acceleration lowered to fit, so the sampled cycle repeats): each
    reversal side passes ``steps`` places a ``count / steps`` apart on the loop encoder's grid, whatever the
    offset, and with ``steps`` odd both sides pass all of them (the module's text). Every half-period starts and
    ends at the offset: no step in the command.

    Parameters
    ----------
    spec : GentleSpec
        The steady sine (:func:`monitor_spec` ``("sine", ...)``): its amplitude, peak acceleration and offset.
    count : float
        The loop encoder's count, unit of ``u`` (the readings' resolution), ``> 0`` and under ``amplitude``.
    steps : int
        Places on the grid, ``>= 1`` (1: the steady sine, half-periods of one amplitude).
    n : int
        Samples from ``start``.
    start : int
        The first sample's index (a stream's chunk; default 0): the samples equal those of one call from 0.
    whole : bool
        Half-periods of whole samples (default :data:`WHOLE_HALVES`, off: of the length the peak acceleration
        gives, as before moncyc22).
    phases : int
        Sample phases the peaks pass evenly (default :data:`EVEN_PHASES`, 0: off; else ``>= 2``, and ``whole``
        off): the lengths of :func:`half_periods`. Coprime to ``steps``, every amplitude passes all of them; with
        ``phases = steps`` each amplitude keeps one and the sampled cycle repeats every cycle.

    Returns
    -------
    ndarray
        Inside ``offset +/- amplitude`` (the amplitudes only go down from the steady sine's), each half-period at
        most at its peak acceleration, so its steepest slope is at most the steady sine's.
    """
    amplitude, accel = float(spec.amplitude), float(spec.accel or 0.0)
    if not (0.0 < count < amplitude and math.isfinite(count)):
        raise ValueError(f"count must lie in (0, amplitude = {amplitude:g}), not {count!r}")
    if steps < 1:
        raise ValueError(f"steps must be 1 or more, not {steps!r}")
    if phases and (whole or phases < 2):
        raise ValueError(f"phases must be 0, or 2 or more without whole, not {phases!r}")
    amps = amplitude - np.arange(steps) * count / steps
    halves = np.pi * np.sqrt(amps / accel)  # samples per half-period at the peak acceleration
    if phases:
        halves = half_periods(amps, accel, phases)
    if whole:
        halves = np.ceil(halves - 1e-9)  # (the tolerance: a length that is whole up to rounding stays as it is)
    per_cycle = float(np.sum(halves))
    t = np.arange(start, start + n, dtype=np.float64)
    cycles = np.floor(t / per_cycle)
    rest = t - cycles * per_cycle
    ends = np.cumsum(halves)
    k = np.minimum(np.searchsorted(ends, rest, side="right"), steps - 1)
    begin = ends[k] - halves[k]
    half = (cycles.astype(np.int64) * steps + k) % 2  # the sides alternate half-period by half-period
    sign = np.where(half == 0, 1.0, -1.0)
    out: np.ndarray = spec.offset + sign * amps[k] * np.sin(np.pi * (rest - begin) / halves[k])
    return out
