"""The online estimate of the servo-loop model: a moving-window output-error refit, warm-started, off the sampling thread.

Why not the MRGIA: it estimates the pseudo-Wiener model only, whose structure
is wrong for a servo that closes its loop through the play or stalls on
friction (issue 12), and its convergence condition fails above about 10x the
loop's bandwidth (issue 15). The structure that fits physical servos, the
grey-box servo loop (:mod:`servoid.ident.models.servo_loop`), has no
recursive estimator; it has a cheap output-error refit from a near answer
(:func:`servoid.ident.offline.loop_fit.refit_loop`). So the online estimate is
a receding-horizon fit:

* the stream is buffered as it comes, at most two windows of it (constant
  memory: a monitor runs for days; a lost sample is kept with its command:
  the simulation runs through it, the fit does not score it);
* every :attr:`WindowConfig.every_s` of servo time, once
  :attr:`WindowConfig.first_s` have come, the last :attr:`WindowConfig.window_s`
  (all of it while shorter) are refitted. The first window has no answer to
  start from: it runs :func:`~servoid.ident.offline.loop_fit.fit_loop` (both
  places of the play, chosen by validation; a live run's with the load stage,
  ``load=None``, as its answer's search: without it the CiA 402 twin's first
  window put the play in the loop at -59 %), unless a start is given (a model
  file's loop: the monitor); every later one is :func:`refit_loop` from the
  previous answer, and the first fit's best model of the other place of the play
  beside it: the better fit of the window names the place (a first window of 10 s
  named it wrong on the CiA 402 and XM430 twins where 40 s did not; issue 15), and
  when the other place fits better the window is searched afresh (the other
  place's model came from the short first window: on the XM430 twin's seed-1
  record its warm refits stayed at +47 %, a search of 15 s found -6 %). A warm
  refit of the last window off its floor (more than
  :data:`~servoid.ident.offline.intervals.MAX_FIT_TO_FLOOR` times it) on a window
  at least :data:`LOOK_AGAIN` times as long as the last one searched from scratch
  has a second look: the window is searched afresh and the search's answer,
  refitted warm as the others, stays when it fits the window better (a 10 s
  first window's search can find the wrong basin of the right place: on the
  XM430 twin's seed-1 live record a hump at ``kv`` 311, +44 %, its warm refits
  stuck there at 1.3x the floor; the search at 20 s found ``kv`` 149, +5 %). So has
  such a window, on or off its floor, when the last search from scratch did not
  name the place (its validation margin under
  :data:`~servoid.ident.offline.intervals.MIN_STRUCTURE_MARGIN`, :attr:`WindowRow.margin`).
  On a real clock with the stream's end known a look is not started that the longest
  search so far, scaled to the window's length, says cannot end before it (the
  XM430 through the ODrive emulator at load 7: a look at 20 s of 26.7 s beside the
  answer's early search ran past the end and was abandoned, leaving 2 refits, too
  few to judge; the warm refit it replaced took 0.3 s).
  A look due once a live answer's early search has all its samples
  (``early``, :class:`~servoid.ident.online.early_search.EarlySearch`: the fast
  part's first 3/4, the samples of a live run's look at 20 s) does not search
  again: it takes that search's answer, refitted warm on the window like the
  others (on a virtual clock it waits for the search; on a real one it takes it
  once it has ended, at this window or a later one, and costs the worker one
  warm refit: the two searches of the same 20 s had run side by side on a
  loaded 2-core machine).
  The first window's search, as it ends (on the worker, before its warm refit, and even when the refit is
  then stopped at the stream's end), is handed to the answer's head search (``early``, which on a slow
  machine searches the head warm from that search's load: ``EarlySearch.offer``) and, where it names the
  play outside the loop, starts the slow phase's held search (``slow_early``);
  the first :attr:`WindowConfig.burn_in_s` of each window are simulated, not scored:
  where in the play the motor side starts is unknown;
  on a real clock with a wall budget (``budget``), a first window's search still running when the stream
  ends is not stopped there: it carries on, at the worker's own priority, until it ends or the budget's
  deadline, and is handed to the head's search as it ends (``early``'s warm head, which waits for it), its
  window's own warm refit then stopped (:attr:`WindowResult.carried`): on the CiA 402 twin under load the
  first window's search had 3.5 s of its 7 s of CPU by the run's end, and the head then searched from
  scratch with the load stage (14 s of CPU) in the 10 s left (docs/online.md, sixteenth pass);
* after a live design's slow phase (``slow``: its first samples, set aside, the
  windows timed from its end) the place of the play decides what a window
  scores (issue 15): inside the loop the last window, as above; outside it the
  slow phase, whose set point decelerates gently enough for the load to show the
  whole play at each reversal where the fast phase lets it coast (the CiA 402 and
  ODrive twins: the last windows' play -47 ... -74 %), unless the last search of the
  last window tied (the refinement's step-4 rule: the slow part sizes only a place
  the fast part names; the XM430 through the serial emulator: a first window outside
  the loop at +172 %, margin 4.3 %, and the slow phase's search answered +287 %,
  the windows stuck there; now they stay on the last window, whose second look at
  20 s puts the play in the loop at +11 %). The first time a window does, it
  searches the slow phase afresh (or starts ``slow_early``'s held search of it on that search's
  own thread and takes it: on a real clock once it has ended, the window staying on the last
  window until then and the worker free for the next windows), as the live answer does
  (:func:`~servoid.ident.online.refinement.refine_online`, step 4: a warm refit
  of the fast phase's model on it does not leave that model's play), and that
  search stands only when it too puts the play outside the loop (else the windows
  stay on the last window); later windows refit its answer warm on the slow
  phase. The search is kept (:attr:`WindowResult.slow_search`): the refinement
  takes it instead of running it again;
* the refit runs on one worker thread (``background=True``): the simulation is
  numba-compiled with ``nogil``, so the sampler keeps its GIL share; the
  feed only hands over a copy of the window (:attr:`WindowResult.stall_s` is
  the longest time :meth:`update` ever took). While the worker lives, the
  interpreter's switch interval is at most :data:`SWITCH_INTERVAL_S` (restored
  by :meth:`WindowRefit.result`): with Python's 5 ms a sampler waiting for the
  GIL behind the fit's Python code missed 2.5x as many 200 Hz slots on a loaded
  2-core machine (293 against 116 of 4000 late by half a period); at 0.5 ms,
  138 against 102 (docs/online.md). The worker also runs at a lower
  scheduling priority (:data:`WORKER_NICENESS`; Linux), so that on a busy
  machine the sampler's thread goes first. A window that falls due while
  the previous refit still runs is left out (:attr:`WindowResult.dropped`),
  unless ``wait=True`` (a servo on a virtual clock, which runs faster than
  real time: there waiting costs no sample); ``background=False`` runs each
  refit inside :meth:`update` (replays, tests: deterministic);
* when the stream's length is known (``end``: a live identify) a refit is not
  started on a real clock when the last refits' wall time says it cannot end
  within ``grace_s`` of the stream's end (:attr:`WindowResult.late`: on the CiA 402 twin refits
  took 5-16 s, and the one running at the run's end was waited for, up to 14 s
  of wall time, issue 15); :meth:`WindowRefit.result` with ``wait=False``
  waits ``wait_s`` at most for a running refit: then it is told to stop at its next fit
  (:attr:`WindowResult.abandoned`) and the newest finished window is the
  estimate, :attr:`WindowResult.age_s` old.

Each refit is one row of :attr:`WindowResult.history`: the servo time of the
window's end, the play, the free-run NRMSE on the window and the window's
noise floor (:func:`~servoid.ident.offline.intervals.floor_nrmse`). Whether the
estimate has converged is judged on those rows
(:func:`servoid.ident.online.verdict.judge_window`).
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as futures_wait
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import PLAY_IN_LOOP

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.offline._threads import Stop
    from servoid.ident.offline.loop_fit import LoopChoice
    from servoid.ident.online.early_search import EarlySearch

__all__ = [
    "WindowConfig",
    "WindowRow",
    "WindowResult",
    "WindowRefit",
    "WINDOW_S",
    "EVERY_S",
    "FIRST_S",
    "BURN_IN_S",
    "SWITCH_INTERVAL_S",
    "HISTORY_ROWS",
    "LaterFit",
    "SlowSearch",
    "Cancelled",
    "END_GRACE_S",
]

#: Servo seconds refitted each time: long enough for tens of reversals at a designed
#: excitation's holds, short enough that a refit costs well under :data:`EVERY_S` (0.1-0.6 s
#: measured for 10-30 s windows at 200 Hz on a shared machine; docs/online.md).
WINDOW_S = 30.0
#: Servo seconds between refits.
EVERY_S = 5.0
#: Servo seconds before the first fit (both places of the play, from scratch).
FIRST_S = 10.0
#: Servo seconds at a window's start that are simulated but not scored.
BURN_IN_S = 1.0
#: scipy's ``max_nfev`` of a warm refit.
MAX_NFEV = 10
#: How much lower the worker thread's scheduling priority is than the sampler's (``nice``).
WORKER_NICENESS = 10
#: Largest interpreter switch interval while a worker refits, s (the module's text).
SWITCH_INTERVAL_S = 0.0005
#: A window's fit after the first: ``(u, y, score, held) -> (model, nrmse)`` (:class:`WindowRefit`'s ``later``).
LaterFit = Callable[[np.ndarray, np.ndarray, np.ndarray, ServoLoopModel], tuple[ServoLoopModel, float]]
#: Where a window's scored samples come from (:attr:`WindowRow.part`): the last window, or the design's slow phase.
LAST, SLOW = "last", "slow"
#: Refits :attr:`WindowResult.history` keeps (the last ones): a monitor refits for days, identify's
#: refits every 5 s fill it in 5.7 h.
HISTORY_ROWS = 4096
#: Refits whose wall time predicts the next one's (the longest of them: :class:`WindowRefit`'s ``end``).
PREDICT_ROWS = 3
#: How many times longer than the last search from scratch of the last window (the first window's, a changed
#: place's) a window must be for a warm refit off its floor (:data:`~servoid.ident.offline.intervals.MAX_FIT_TO_FLOOR`)
#: to have it searched afresh (any warm refit, when that search did not name the place; the module's text): a first
#: window of 10 s, a second look at 20 s, none after on 30 s windows. On the XM430 twin's seed-1 live record the first window's search put the play in the loop with a hump
#: at ``kv`` 311 (+44 %) and the warm refits stayed there (1.3x the floor); a search of 20 s found ``kv`` 149.
LOOK_AGAIN = 2.0
#: Wall seconds a live identify lets a window refit run past the stream's end (:class:`WindowRefit`'s ``grace_s``,
#: :meth:`WindowRefit.result`'s ``wait_s``): about what the answer's refinement takes after the run anyway
#: (0.3-3.6 s, docs/online.md); without it the CiA 402 twin's refit due 4 s before the end (5.0 s) was not started
#: and the verdict had 2 refits, too few to judge.
END_GRACE_S = 2.0


class Cancelled(Exception):
    """A window refit told to stop (:meth:`WindowRefit.result` with ``wait=False``) stopped between its fits."""


def _check(stop: threading.Event | None) -> None:
    """Raise :class:`Cancelled` when the refit has been told to stop (called between a refit's fits)."""
    if stop is not None and stop.is_set():
        raise Cancelled("the window refit was stopped at the stream's end")


def _stoppable(stop: threading.Event, work: Callable[..., Any], *job: Any, deadline_s: float = math.inf) -> Any:
    """``work(*job)`` on the worker, its fits stopped inside (:func:`._threads.stopping`) once ``stop`` is set (or at
    ``deadline_s``, a wall budget's :func:`time.perf_counter` instant: a first window's search carried past the
    stream's end): a refit told to stop frees the CPU at its next simulation, not at its next fit (raised as
    :class:`Cancelled`)."""
    from servoid.ident.offline import _threads

    try:
        with _threads.stopping(_threads.Stop(deadline_s, why="the stream's end", event=stop)):
            return work(*job)
    except _threads.Stopped as exc:
        raise Cancelled(f"the window refit was {exc}") from exc


@dataclass(frozen=True)
class WindowConfig:
    """Settings of :class:`WindowRefit`.

    Attributes
    ----------
    sample_period_s : float
        The period of the stream the estimator is fed, s.
    window_s : float
        Servo seconds refitted each time (the last ones).
    every_s : float
        Servo seconds between refits.
    first_s : float
        Servo seconds before the first fit.
    burn_in_s : float
        Servo seconds at a window's start simulated but not scored.
    max_nfev : int
        Evaluations of each warm refit.

    The first refit fits the last ``max(window_s, first_s)`` (a monitor's first fit may be
    longer than its windows), every later one the last ``window_s``.
    """

    sample_period_s: float
    window_s: float = WINDOW_S
    every_s: float = EVERY_S
    first_s: float = FIRST_S
    burn_in_s: float = BURN_IN_S
    max_nfev: int = MAX_NFEV

    def __post_init__(self) -> None:
        for name in ("sample_period_s", "window_s", "every_s", "first_s"):
            validation.positive(name, getattr(self, name))
        validation.non_negative("burn_in_s", self.burn_in_s)
        validation.integer("max_nfev", self.max_nfev, minimum=1)
        if self.burn_in_s >= min(self.window_s, self.first_s):
            raise ConfigError(f"burn_in_s (={self.burn_in_s:g}) must be shorter than window_s and first_s")

    def samples(self, seconds: float) -> int:
        """Samples of ``seconds`` of servo time (at least 1)."""
        return max(1, int(round(seconds / self.sample_period_s)))

    def to_dict(self) -> dict[str, Any]:
        """For JSON: the fields by name."""
        return {"sample_period_s": self.sample_period_s, "window_s": self.window_s, "every_s": self.every_s,
                "first_s": self.first_s, "burn_in_s": self.burn_in_s, "max_nfev": self.max_nfev}  # fmt: skip


@dataclass(frozen=True)
class WindowRow:
    """One refit of :class:`WindowRefit`.

    Attributes
    ----------
    t_s : float
        Servo time of the window's end, s.
    play : float
        ``c1 + c2`` of the refitted model.
    nrmse : float
        Its free-run NRMSE on the window's scored samples.
    floor : float
        The NRMSE the window's resolution and noise leave.
    seconds : float
        Wall time of the refit.
    structure : str
        Where the play sits in the refitted model.
    part : str
        The samples it scored: ``"last"`` (the last window) or ``"slow"`` (the design's slow phase).
    reversals : int
        Reversals of the window's scored readings by more than twice the play the window's fit
        started from (:func:`~servoid.ident.offline.intervals.reversals`, identify's rule): each
        is the motor crossing the play, what the window says about it. -1: not counted.
    searched : bool
        The refit ran a search from scratch (:func:`~servoid.ident.offline.loop_fit.fit_loop`: the
        first window, a changed place, the slow phase's first look), many times a warm refit's cost.
    margin : float
        When the last window was searched from scratch (the first window, a changed place, a second
        look), that search's validation margin between the places of the play
        (:attr:`~servoid.ident.offline.loop_fit.LoopChoice.margin`); NaN when it was not.
    """

    t_s: float
    play: float
    nrmse: float
    floor: float
    seconds: float
    structure: str
    part: str = LAST
    reversals: int = -1
    searched: bool = False
    margin: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """For JSON."""
        return {"t_s": self.t_s, "play": self.play, "nrmse": self.nrmse, "floor": self.floor,
                "seconds": self.seconds, "structure": self.structure, "part": self.part,
                "reversals": self.reversals, "searched": self.searched, "margin": self.margin}  # fmt: skip


@dataclass(frozen=True)
class SlowSearch:
    """The window refit's search of a live design's slow phase (:class:`WindowRefit`'s ``slow``).

    Attributes
    ----------
    choice : LoopChoice
        :func:`~servoid.ident.offline.loop_fit.fit_loop` (``load=None``) on the slow phase.
    start : int
        Index, in the stream, of the slow phase's first measured sample, where the search starts.
    samples : int
        Samples it covered (from ``start`` to the slow phase's end).
    """

    choice: LoopChoice
    start: int
    samples: int


#: The slow phase as :func:`_refit_later` takes it: ``u, y, keep`` from its first measured sample, that sample's
#: index, its model so far (None before its search), and its own search when one runs (``slow_early``).
SlowJob = tuple[np.ndarray, np.ndarray, np.ndarray, int, ServoLoopModel | None,
                Callable[[], SlowSearch | None] | None]  # fmt: skip


@dataclass(frozen=True)
class WindowResult:
    """What a :class:`WindowRefit` run produced.

    Attributes
    ----------
    model : ServoLoopModel or None
        The last refit's model (None: no window was fitted).
    history : tuple of WindowRow
        The refits in order, the last :data:`HISTORY_ROWS` of them.
    config : WindowConfig
        The settings.
    dropped : int
        Windows left out because the previous refit was still running.
    stall_s : float
        Longest wall time one :meth:`WindowRefit.update` took (what the sampler waited; a wait
        for the last refit with ``wait=True`` is not counted).
    errors : tuple of str
        Refits that failed, with why.
    rival : ServoLoopModel or None
        The model with the play in the other place: the first fit's best one, refitted on every
        later window beside the named place's (None when the run started from a given model).
    slow_search : SlowSearch or None
        The search of the design's slow phase, when a window ran it (whichever place it named).
    end_s : float
        Servo time of the stream's end on the windows' clock (from the slow phase's end), s; NaN: not given.
    late : int
        Refits not started because the last refits' wall time said they could not end before the stream.
    abandoned : int
        Refits running at the stream's end that were not waited for (told to stop, their result dropped).
    carried : bool
        Whether the first window's search was running at the stream's end and carried on for the head's
        search (:class:`WindowRefit`'s ``budget``; counted in ``abandoned`` too: no window model came of it).
    """

    model: ServoLoopModel | None
    history: tuple[WindowRow, ...]
    config: WindowConfig
    dropped: int
    stall_s: float
    errors: tuple[str, ...] = field(default=())
    rival: ServoLoopModel | None = None
    slow_search: SlowSearch | None = None
    end_s: float = math.nan
    late: int = 0
    abandoned: int = 0
    carried: bool = False

    @property
    def age_s(self) -> float:
        """Servo seconds between the last refit's window end and the stream's end (NaN: no refit or no end)."""
        return self.end_s - self.history[-1].t_s if self.history else math.nan

    @property
    def plays(self) -> np.ndarray:
        """The play of each refit."""
        return np.array([r.play for r in self.history], dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """For JSON (the history as rows)."""
        return {"model": None if self.model is None else self.model.to_dict(),
                "history": [r.to_dict() for r in self.history], "config": self.config.to_dict(),
                "dropped": self.dropped, "stall_s": self.stall_s, "errors": list(self.errors),
                "end_s": self.end_s, "age_s": self.age_s, "late": self.late, "abandoned": self.abandoned,
                "carried": self.carried, "slow_search": None if self.slow_search is None else {
                    "structure": self.slow_search.choice.structure, "play": self.slow_search.choice.play,
                    "samples": self.slow_search.samples}}  # fmt: skip


def _refit(
    u: np.ndarray,
    y: np.ndarray,
    keep: np.ndarray,
    start: ServoLoopModel | None,
    config: WindowConfig,
    t_s: float,
    later: LaterFit | None = None,
    load: bool | None = False,
    stop: threading.Event | None = None,
    searched: Callable[[LoopChoice | None, float, int], None] | None = None,
) -> tuple[ServoLoopModel, WindowRow, ServoLoopModel | None]:
    """Fit one window (the worker's job): from scratch with both places of the play, or warm from ``start``.

    ``later``: the fit to use instead of :func:`refit_loop` (``later(u, y, score, start)``); ``load``:
    :func:`fit_loop`'s load stage in the fit from scratch; ``stop``: set, the refit raises :class:`Cancelled`
    between its fits; ``searched``: told the fit from scratch's answer, its wall seconds and samples as it ends
    (None: it failed), even when the refit is then stopped (:meth:`WindowRefit._first_searched`).
    Returns the model, its row, and from the first fit the best model of the other place of
    the play (the rival the later windows refit beside it; None after).
    """
    from servoid.ident.offline.intervals import floor_nrmse, reversals
    from servoid.ident.offline.loop_fit import fit_loop, refit_loop

    t0 = time.perf_counter()
    burn = min(config.samples(config.burn_in_s), u.size - 2)
    score = keep.copy()
    score[:burn] = False
    if start is None:
        # fit_loop needs every sample: lost readings are bridged linearly (only this first look; the
        # warm refits leave them out), from the first measured one
        idx = np.flatnonzero(keep)
        filled = np.interp(np.arange(u.size), idx, y[idx])
        try:
            choice = fit_loop(u, filled, config.sample_period_s, load=load, light_rivals=False)
        except BaseException:
            if searched is not None:
                searched(None, time.perf_counter() - t0, int(u.size))
            raise
        if searched is not None:
            searched(choice, time.perf_counter() - t0, int(u.size))
        model, margin = choice.model, float(choice.margin)
        rival = next((c.model for c in choice.candidates if c.structure != choice.structure), None)
    else:
        model, rival, margin = start, None, math.nan
    _check(stop)
    turns = reversals(y[score], 2.0 * model.play)
    if later is not None:
        model, q = later(u, y, score, model)
    else:
        fit = refit_loop(u, y, model, score=score, max_nfev=config.max_nfev)
        model, q = fit.model, fit.fit_nrmse
    row = WindowRow(t_s, model.play, q, floor_nrmse(y[score]), time.perf_counter() - t0, model.structure,
                    reversals=turns, searched=start is None, margin=margin)  # fmt: skip
    return model, row, rival


def _looks_again(slow_answers: bool, nrmse: float, floor: float) -> bool:
    """Whether a window's warm fit asks for a second look: off its floor where the slow phase does not answer.

    Off the floor: above :data:`~servoid.ident.offline.intervals.MAX_FIT_TO_FLOOR` times it. (A look is also due
    after a tied search, whatever the fit.)
    """
    from servoid.ident.offline.intervals import MAX_FIT_TO_FLOOR

    return not (slow_answers or nrmse <= MAX_FIT_TO_FLOOR * floor)


def _refit_later(
    u: np.ndarray,
    y: np.ndarray,
    keep: np.ndarray,
    fast: ServoLoopModel,
    rival: ServoLoopModel | None,
    config: WindowConfig,
    t_s: float,
    slow: SlowJob | None,
    load: bool | None = False,
    look: bool = False,
    tied: bool = False,
    early: Callable[[], SlowSearch | None] | None = None,
    stop: threading.Event | None = None,
) -> tuple[ServoLoopModel, WindowRow, ServoLoopModel | None, SlowSearch | None, ServoLoopModel]:
    """Fit a window after the first of a run with a rival place or a slow phase (the worker's job; the module's text).

    The last window's model (``fast``) and the other place's (``rival``) are refitted warm on the
    window; the better fit names the place. When that is the rival's (the place changed), the
    window is searched afresh (:func:`fit_loop` with ``load``, both places): the rival came from a
    shorter first window and a warm refit does not leave its play. With the play outside the loop and ``slow`` (the slow
    phase's ``u, y, keep``, the stream index of its first sample, its model: None before the
    search, and the slow phase's own search, ``slow_early``'s, when one runs: None while it runs on a
    real clock) the slow phase answers: searched afresh (:func:`fit_loop`, ``load=None``, as the live
    answer searches it; standing only when it too puts the play outside the loop) or that search
    taken (the window stays on the last window while it runs), else its model refitted warm. With ``look`` (the window is :data:`LOOK_AGAIN` times as long as the last one
    searched from scratch), a last window whose warm fit is off its floor and which the slow phase
    does not answer, or any window when ``tied`` (that search's places tied), is searched afresh too; the search's answer refitted warm stays when it fits the
    window better (the row is ``searched`` either way). With ``early`` (a live answer's early search, its
    samples all come) that search's answer is the look's instead of a search of the window; when it
    returns None (not ended on a real clock) the window has no look (a later one may). Returns the estimate, its row, the other
    place's model, the search (None: none ran) and the winning place's model of the last window.
    """
    from servoid.ident.offline.intervals import floor_nrmse, reversals
    from servoid.ident.offline.loop_fit import fit_loop, refit_loop

    t0 = time.perf_counter()
    score = keep.copy()
    score[: min(config.samples(config.burn_in_s), u.size - 2)] = False
    turns = reversals(y[score], 2.0 * fast.play)
    fits = []
    for m in (fast, rival):
        if m is not None:
            _check(stop)
            fits.append(refit_loop(u, y, m, score=score, max_nfev=config.max_nfev))
    best = min(fits, key=lambda f: f.fit_nrmse)
    won, q = best.model, best.fit_nrmse
    other = next((f.model for f in fits if f is not best), None)
    searched = best is not fits[0]
    idx = np.flatnonzero(keep)

    def afresh() -> Any:
        """Both places searched from scratch on this window (lost readings bridged; no interval is reported)."""
        _check(stop)
        return fit_loop(
            u,
            np.interp(np.arange(u.size), idx, y[idx]),
            config.sample_period_s,
            keep=keep,
            load=load,
            light_rivals=False,
        )

    margin = math.nan
    if searched:  # the place changed: both places searched afresh on this window
        choice = afresh()
        won, q, margin = choice.model, choice.fit_nrmse, float(choice.margin)
        other = next((c.model for c in choice.candidates if c.structure != choice.structure), None)
    floor = floor_nrmse(y[score])
    scores_slow = slow is not None and won.structure != PLAY_IN_LOOP  # the slow phase answers, not this window
    if look and not searched and (tied or _looks_again(scores_slow, q, floor)):
        # a second look: the last search tied, or the warm refits stay in the basin a shorter window's search found;
        # searched afresh (or the early search of the window's head taken), the search's answer refitted as the warm
        # ones were, the better fit of the window stays
        found = None if early is None else early()
        chosen = afresh() if early is None else (None if found is None else found.choice)
        if chosen is not None:
            _check(stop)
            again = refit_loop(u, y, chosen.model, score=score, max_nfev=config.max_nfev)
            searched, margin = True, float(chosen.margin)
            if again.fit_nrmse < q:
                won, q = again.model, again.fit_nrmse
                other = next((c.model for c in chosen.candidates if c.structure != won.structure), other)
    model, part, search = won, LAST, None
    if slow is not None and won.structure != PLAY_IN_LOOP:
        _check(stop)
        su, sy, sk, offset, held, shared = slow
        if held is None:
            search = None if shared is None else shared()  # the slow phase's own search (None: still running)
            if search is not None and search.samples != su.size:
                search = shared = None  # not these samples: searched here
            if shared is None:
                choice = fit_loop(
                    su, sy, config.sample_period_s, keep=sk, load=None
                )  # the answer may reuse its interval
                search = SlowSearch(choice, offset, int(su.size))
            if search is not None:
                searched = True
                if search.choice.structure != PLAY_IN_LOOP:
                    model, q, floor, part = search.choice.model, search.choice.fit_nrmse, floor_nrmse(sy[sk]), SLOW
                    turns = reversals(sy[sk], 2.0 * fast.play)
        else:
            sscore = sk.copy()
            sscore[: min(config.samples(config.burn_in_s), su.size - 2)] = False
            fit = refit_loop(su, sy, held, score=sscore, max_nfev=config.max_nfev)
            model, q, floor, part = fit.model, fit.fit_nrmse, floor_nrmse(sy[sscore]), SLOW
            turns = reversals(sy[sscore], 2.0 * held.play)
    row = WindowRow(t_s, model.play, q, floor, time.perf_counter() - t0, model.structure, part, turns, searched, margin)
    return model, row, other, search, won


def _yield_cpu() -> tuple[int, int] | None:
    """Lower the worker thread's scheduling priority (Linux sets it per thread): on a busy machine the sampler goes
    first. Returns the thread's native id and its niceness before (:func:`_unyield` gives it back), None: unchanged."""
    try:
        tid = threading.get_native_id()
        before = os.getpriority(os.PRIO_PROCESS, tid)
        os.setpriority(os.PRIO_PROCESS, tid, min(19, before + WORKER_NICENESS))
    except (AttributeError, OSError):  # not Linux, or not permitted: the thread keeps its priority
        return None
    return tid, before


def _unyield(niced: tuple[int, int] | None) -> None:
    """Give a thread of this process the niceness :func:`_yield_cpu` took from it, where permitted (a process may
    raise a thread's priority only with ``CAP_SYS_NICE`` or an ``RLIMIT_NICE``, as it may take ``SCHED_FIFO``)."""
    if niced is None or not os.path.exists(f"/proc/self/task/{niced[0]}"):  # none, or the thread has ended
        return
    try:
        os.setpriority(os.PRIO_PROCESS, niced[0], niced[1])
    except OSError:  # not permitted: it keeps the lower priority
        pass


class WindowRefit:
    """An :class:`~servoid.ident.online.estimator.Estimator` of the servo-loop model (the module's method).

    Parameters
    ----------
    config : WindowConfig
        Window, refit period, burn-in.
    start : ServoLoopModel, optional
        The model to start from (a model file's loop); default: :func:`fit_loop` on the first window.
    background : bool
        Refit on a worker thread (a live session) or inside :meth:`update` (a replay).
    wait : bool
        When a window falls due while the last refit still runs, wait for it (a virtual
        clock) instead of leaving the window out (a live servo: the sampler must not wait).
    later : callable, optional
        The fit of every window after the first, ``later(u, y, score, held) -> (model, nrmse)``,
        ``held`` the first fit's model (the monitor's play-only estimate,
        :func:`servoid.ident.monitoring.play_fit.fit_play`); default
        :func:`~servoid.ident.offline.loop_fit.refit_loop` from the last answer.
    first : callable, optional
        The fit of the first window from ``start``, ``first(u, y, score, start) -> (model, nrmse)``
        (the monitor's :func:`servoid.ident.monitoring.loop_wear.first_refit`); default
        :func:`~servoid.ident.offline.loop_fit.refit_loop` from ``start``. Unused without a start.
    slow : int
        How many of the stream's first samples are a live design's slow phase: kept aside, the
        windows timed from its end, scored by the windows once they put the play outside the
        loop (the module's text; 0: none).
    load : bool or None
        :func:`~servoid.ident.offline.loop_fit.fit_loop`'s load stage in the first fit (a live
        run: None, as the live answer's search; default False).
    end : int
        Samples the stream will hold in all, the slow phase's included (a live run's length; 0:
        not known). With a worker and a real clock (not ``wait``), a refit is not started when the
        longest of the last :data:`PREDICT_ROWS` refits (the warm ones once there are any, not the
        searches from scratch, :attr:`WindowRow.searched`) took more wall time than the servo time left
        (:attr:`WindowResult.late`).
    grace_s : float
        Wall seconds a refit may run past the stream's end in that rule (a live identify:
        :data:`END_GRACE_S`).
    early : EarlySearch, optional
        A live answer's search of the fast part's head, fed the same stream before this refit (its
        ``skip`` this ``slow``): a second look due once its samples have all come takes its answer
        instead of searching again (the module's text).
    slow_early : EarlySearch, optional
        The slow phase's search on a thread of its own (``at`` this ``slow``, ``skip`` 0, ``hold``:
        started by the first window that asks for it), fed the same stream before this refit: the
        windows take it instead of searching the slow phase on the worker (the module's text).
    budget : Stop, optional
        A live run's wall budget on a real clock: with ``early``, a first window's search still
        running when :meth:`result` would stop it carries on until it ends or the budget's deadline,
        for ``early`` (the module's text; :attr:`WindowResult.carried`). None (default): it is
        stopped there, as every refit.
    """

    def __init__(
        self,
        config: WindowConfig,
        *,
        start: ServoLoopModel | None = None,
        background: bool = True,
        wait: bool = False,
        later: LaterFit | None = None,
        first: LaterFit | None = None,
        slow: int = 0,
        load: bool | None = False,
        end: int = 0,
        grace_s: float = 0.0,
        early: EarlySearch | None = None,
        slow_early: EarlySearch | None = None,
        budget: Stop | None = None,
    ) -> None:
        if not isinstance(config, WindowConfig):
            raise ConfigError(f"config must be a WindowConfig, not {type(config).__name__}")
        if start is not None and not math.isclose(start.sample_period_s, config.sample_period_s, rel_tol=1e-6):
            raise ConfigError(f"the start model's period ({start.sample_period_s:g} s) is not the stream's "
                              f"({config.sample_period_s:g} s)")  # fmt: skip
        self.config = config
        self.model = start
        self._later = later
        self._first_fit = first if start is not None else None
        self._held: ServoLoopModel | None = None  # the first fit's model, which ``later`` holds
        self._u: list[float] = []
        self._y: list[float] = []
        self._keep: list[bool] = []
        self._n = 0  # samples taken in all
        self._window = config.samples(config.window_s)
        self._every = config.samples(config.every_s)
        self._first = config.samples(config.first_s)
        self._history: list[WindowRow] = []
        self._gone = 0  # refits dropped from the front of _history (bounded memory)
        self._errors: list[str] = []
        self._dropped = 0
        self._stall = 0.0
        self._niced: tuple[int, int] | None = None  # the worker's thread id and niceness before it was lowered
        self._pool = (
            ThreadPoolExecutor(max_workers=1, thread_name_prefix="servoid-window", initializer=self._lower)
            if background
            else None
        )
        self._switch = sys.getswitchinterval()
        if background:
            sys.setswitchinterval(min(self._switch, SWITCH_INTERVAL_S))
        self._future: Future[tuple[Any, ...]] | None = None
        self._rival: ServoLoopModel | None = None
        self._wait = bool(wait)
        self._waited = 0.0  # of the current sample, on a virtual clock: not a stall of a real sampler
        self._slow = validation.integer("slow", slow, minimum=0)
        self._slow_u: list[float] = []
        self._slow_y: list[float] = []
        self._slow_keep: list[bool] = []
        self._search: SlowSearch | None = None  # the slow phase's search, once a window ran it
        self._slow_model: ServoLoopModel | None = None  # the slow phase's estimate, once searched
        self._fast: ServoLoopModel | None = None  # the last window's model of the place it named
        self._load = load
        self._end = validation.integer("end", end, minimum=0)
        self._grace = validation.non_negative("grace_s", grace_s)
        self._late = 0  # refits not started: they could not end before the stream
        self._abandoned = 0  # refits running at the stream's end, not waited for
        self._stop = threading.Event()  # set: a running refit stops at its next fit
        self._looked = 0  # samples of the last window searched from scratch (0: none yet)
        self._tied = False  # that search's places tied (validation margin under MIN_STRUCTURE_MARGIN)
        self._span_due = 0  # samples of the window the refit in hand fits
        self._early = early
        self._slow_early = slow_early
        self._offering = False  # the first window's search was started: it offers its model to ``early`` as it ends
        self._budget = budget
        self._deadline_s = math.inf if budget is None else budget.deadline_s
        self._carried: threading.Event | None = None  # the carried first search's stop: set once it has offered

    def _span(self) -> int:
        """Samples the next refit fits: the first ``max(window_s, first_s)``, every later one ``window_s``."""
        return self._window if self._history or self._gone else max(self._window, self._first)

    def update(self, u: float, y: float) -> None:
        """Take a measured sample."""
        self._take(float(u), float(y), True)

    def skip(self, u: float) -> None:
        """Take a sample whose measurement is not to be used (its command still drives the simulation)."""
        self._take(float(u), math.nan, False)

    def _take(self, u: float, y: float, keep: bool) -> None:
        if len(self._slow_u) < self._slow:  # the design's slow phase: set aside, the windows timed from its end
            self._slow_u.append(u)
            self._slow_y.append(y)
            self._slow_keep.append(keep)
            return
        t0 = time.perf_counter()
        self._waited = 0.0
        self._u.append(u)
        self._y.append(y)
        self._keep.append(keep)
        self._n += 1
        n = self._n
        span = self._span()
        if len(self._u) > 2 * span:  # constant memory: only the last window (the first: first_s) is ever fitted
            del self._u[:-span], self._y[:-span], self._keep[:-span]
        if n >= self._first and (n - self._first) % self._every == 0:
            self._due(n)
        self._stall = max(self._stall, time.perf_counter() - t0 - self._waited)

    def _due(self, n: int) -> None:
        t0 = time.perf_counter()
        self._collect(wait=self._wait)
        self._waited = time.perf_counter() - t0 if self._wait else 0.0
        if self._future is not None:
            self._dropped += 1
            return
        if self._too_late(n):
            self._late += 1
            return
        size = len(self._u)
        first = not self._history and not self._gone
        lo = max(0, size - self._span())
        keep = np.array(self._keep[lo:], dtype=np.bool_)
        if not keep.any():
            return
        lo += int(np.argmax(keep))  # the simulation starts at a measured sample
        if size - lo < 4 * self.config.samples(self.config.burn_in_s) or int(np.sum(keep)) < 50:
            return
        t_s = n * self.config.sample_period_s
        window = (np.array(self._u[lo:]), np.array(self._y[lo:]), np.array(self._keep[lo:], dtype=np.bool_))
        work: Callable[..., Any] = _refit
        job: tuple[Any, ...]
        if first or self._later is not None:
            offer = self._first_searched if first and self.model is None else None  # the first window's search
            self._offering = self._offering or offer is not None
            job = (*window, self.model if first else self._held, self.config, t_s, self._first_fit if first else self._later,
                   self._load, self._stop, offer)  # fmt: skip
        else:
            # a second look: a window this much longer than the last search's (none after a given start); the early
            # search's answer once its samples have all come, else a search if it can end before the stream
            look = 0 < self._looked and size - lo >= LOOK_AGAIN * self._looked
            early = self._shared(n) if look else None
            look = look and (early is not None or self._look_ends(n, size - lo))
            work, job = _refit_later, (*window, self._fast, self._rival, self.config, t_s, self._slow_job(), self._load,
                                       look, self._tied, early, self._stop)  # fmt: skip
        self._span_due = size - lo
        if self._pool is None:
            self._store(work, job, t_s)
        else:
            self._future = self._pool.submit(_stoppable, self._stop, work, *job, deadline_s=self._deadline_s)

    def _first_searched(self, choice: LoopChoice | None, seconds: float, samples: int) -> None:
        """The first window's search as it ends (on the worker, before its warm refit; None: it failed): offered to the
        answer's head search (``early``: a slow machine's head searched warm from its load,
        :meth:`~servoid.ident.online.early_search.EarlySearch.offer`), and the slow phase's held search started where
        it names the play outside the loop (as :meth:`_keep_fit` starts it, a warm refit sooner)."""
        from servoid.ident.offline.intervals import MIN_STRUCTURE_MARGIN

        if self._early is not None:
            if choice is None:
                self._early.release()
            else:
                self._early.offer(choice.model, seconds, samples, choice)
        if self._carried is not None:  # carried past the stream's end for the head: its window's refit not wanted
            self._carried.set()
        named = choice is not None and choice.structure != PLAY_IN_LOOP and choice.margin >= MIN_STRUCTURE_MARGIN
        if self._slow_early is not None and named:
            self._slow_early.begin()

    def _too_late(self, n: int) -> bool:
        """Whether a refit due at the ``n``-th sample would still run when the stream ends (a worker on a real clock
        with a known end: the longest of the last :data:`PREDICT_ROWS` refits' wall time against the servo time left)."""
        if self._pool is None or self._wait or not self._end or not self._history:
            return False
        left_s = (self._end - self._slow - n) * self.config.sample_period_s
        warm = [r for r in self._history if not r.searched] or self._history  # a search predicts no warm refit
        return max(r.seconds for r in warm[-PREDICT_ROWS:]) > left_s + self._grace

    def _shared(self, n: int) -> Callable[[], SlowSearch | None] | None:
        """The early search's answer for a second look at the ``n``-th sample, when the search's samples have all
        come and are as many as a look needs (:data:`LOOK_AGAIN` times the last search's); else None."""
        early = self._early
        if early is None or not (LOOK_AGAIN * self._looked <= early.at <= n):
            return None
        wait = self._wait and self._pool is not None  # inline (a replay) the search is taken only once it has ended
        return lambda: early.searched(wait=wait)

    def _look_pending(self, n: int) -> bool:
        """Whether the end of the stream would take a second look from the early search that no window has taken yet
        (the search had not ended: a real clock): :func:`_refit_later`'s rule on the last refit, the last search tied,
        or the last window's fit off its floor where the slow phase does not answer."""
        if self._shared(n) is None or not self._history or self._fast is None:
            return False
        last = self._history[-1]
        slow = self._fast.structure != PLAY_IN_LOOP and self._slow_job() is not None
        return self._tied or (last.part == LAST and _looks_again(slow, last.nrmse, last.floor))

    def _look_ends(self, n: int, span: int) -> bool:
        """Whether a second look at the ``n``-th sample, on ``span`` samples, ends before the stream (the ``late``
        rule for a search: the longest search's wall time so far, scaled to ``span`` from the last search's length;
        always on a virtual clock or with no end known). No ``grace_s``: a look is optional, and one that runs past
        the end costs the verdict the warm refit it replaced."""
        if self._pool is None or self._wait or not self._end:
            return True
        left_s = (self._end - self._slow - n) * self.config.sample_period_s
        cost = max((r.seconds for r in self._history if r.searched), default=0.0) * span / self._looked
        return cost <= left_s

    def _slow_job(self) -> SlowJob | None:
        """The slow phase for :func:`_refit_later` (its samples from the first measured one, that index, its model
        so far, and ``slow_early``'s search of it while it has not failed); None without one, with too few samples,
        when its search put the play inside the loop, or when the last window's last search from scratch tied (the
        place not named: the refinement's step-4 rule)."""
        from servoid.ident.offline.loop_fit import MIN_SAMPLES

        if self._search is not None and self._search.choice.structure == PLAY_IN_LOOP:
            return None  # the slow phase's search did not confirm the place
        if self._tied:
            return None  # the last window did not name the place: the slow phase does not size it
        keep = np.array(self._slow_keep, dtype=np.bool_)
        if int(keep.sum()) < MIN_SAMPLES:
            return None
        lo = int(np.argmax(keep))  # the simulation starts at a measured sample
        early, shared = self._slow_early, None
        if early is not None and early.ready:
            wait = self._wait and self._pool is not None  # a virtual clock waits for it; a real one takes it once ended
            shared = lambda: early.searched(wait=wait)  # noqa: E731
        return np.array(self._slow_u[lo:]), np.array(self._slow_y[lo:]), keep[lo:], lo, self._slow_model, shared

    def _store(self, work: Callable[..., Any], job: tuple[Any, ...], t_s: float) -> None:
        try:
            self._keep_fit(*work(*job))
        except (ConfigError, ValueError, FloatingPointError, OverflowError, np.linalg.LinAlgError) as exc:
            self._errors.append(f"window ending at {t_s:.1f} s: {exc}")

    def _keep_fit(
        self,
        model: ServoLoopModel,
        row: WindowRow,
        rival: ServoLoopModel | None,
        search: SlowSearch | None = None,
        fast: ServoLoopModel | None = None,
    ) -> None:
        self._search = search if search is not None else self._search
        self._slow_model = model if row.part == SLOW else self._slow_model
        self._fast = model if fast is None else fast
        if math.isfinite(row.margin):  # the last window searched from scratch: its length, whether it named the place
            from servoid.ident.offline.intervals import MIN_STRUCTURE_MARGIN

            self._looked, self._tied = self._span_due, not row.margin >= MIN_STRUCTURE_MARGIN
        self.model = model
        self._held = model if self._held is None else self._held
        self._rival = rival
        self._history.append(row)
        if self._slow_early is not None and self._fast.structure != PLAY_IN_LOOP and not self._tied:
            # the next window will ask for the slow phase's held search: started now, on its own thread (the ODrive
            # twin at load 7: the first window's search ended at 15.5 s, the window at 15 s dropped, and a search
            # started by the window at 20 s had not ended by the run's end, the windows never scored the slow phase)
            self._slow_early.begin()
        if len(self._history) > 2 * HISTORY_ROWS:
            del self._history[:-HISTORY_ROWS]
            self._gone += HISTORY_ROWS

    def _collect(self, *, wait: bool) -> None:
        fut = self._future
        if fut is None or not (wait or fut.done()):
            return
        self._future = None
        try:
            fitted = fut.result()
        except Cancelled:
            return
        except (ConfigError, ValueError, FloatingPointError, OverflowError, np.linalg.LinAlgError) as exc:
            self._errors.append(str(exc))
            return
        self._keep_fit(*fitted)

    def rows(self) -> tuple[WindowRow, ...]:
        """The refits finished so far, the last :data:`HISTORY_ROWS` of them (a finished background refit is collected, a running one not waited for)."""
        self._collect(wait=False)
        return tuple(self._history[-HISTORY_ROWS:])

    def rows_since(self, start: int) -> tuple[WindowRow, ...]:
        """The refits finished after the first ``start`` (as :meth:`rows`; a caller per sample copies only new ones).

        Parameters
        ----------
        start : int
            How many refits the caller has seen.
        """
        self._collect(wait=False)
        return tuple(self._history[max(0, start - self._gone) :])

    @property
    def dropped(self) -> int:
        """Windows left out so far because the previous refit was still running."""
        return self._dropped

    @property
    def late(self) -> int:
        """Refits not started so far because they could not end before the stream (the class's ``end``)."""
        return self._late

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the servo-loop simulation and import the refits' modules now, not
        inside the sampling loop.

        Imported by the first refit on the worker instead, the modules (scipy's
        extensions among them) loaded under the import lock the sampler's thread
        also takes (:data:`~servoid.ident.offline.loop_fit.MIN_SAMPLES`), on a
        thread at :data:`WORKER_NICENESS`: a 200 Hz loop at ``SCHED_FIFO`` beside a
        worker's first ``fit_loop``, both on one core with a busy process, had a
        slot 0.52-1.04 s late (6 draws, load 1.7-6; the serial firmware's
        watchdog is 0.5 s, and it switched a live identify's servo off), 35-44 ms
        after this warm-up (3 draws interleaved with 2 of those).
        """
        # (the refinement, which the early search's worker imports, imports this module: live identify imports it
        # before the session, servoid.cli._live)
        import servoid.ident.offline.intervals  # noqa: F401
        import servoid.ident.offline.loop_fit  # noqa: F401

        ServoLoopModel("output_backlash", self.config.sample_period_s, kp=10.0, kv=50.0).simulate(np.zeros(4))

    def current(self) -> Mapping[str, float]:
        """The last refit's play and loop gains (empty before the first)."""
        self._collect(wait=False)
        m = self.model
        return {} if m is None or not self._history else {"play": m.play, "kp": m.kp, "kv": m.kv}

    def close(self) -> None:
        """Stop the worker without another refit and give the interpreter its switch interval back; safe twice.

        For a session that ended in an error: :meth:`result` does the same on the normal way out.
        """
        if self._early is not None:
            self._early.release()
        if self._pool is not None:
            self._stop.set()  # a running refit stops at its next fit
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
            sys.setswitchinterval(self._switch)

    def _lower(self) -> None:
        """The worker's initializer: its priority lowered below the sampler's (:func:`_yield_cpu`), kept to give back."""
        self._niced = _yield_cpu()

    def _bounded(self, wait: bool, wait_s: float) -> None:
        """Collect a running refit: waited for, or (not ``wait``) for ``wait_s`` at most and then told to stop; a
        first window's search not yet ended carried on instead, for ``early`` (``budget``, the module's text).

        A refit still queued (not started) is dropped; where it was the first window's search, ``early`` is released
        (a stopped search tells it itself, :func:`_refit`): a run that ended as its first window fell due left the
        answer's head search waiting for an offer that never came (found by livebus20, issue 15).
        """
        if not wait and self._future is not None and wait_s > 0.0:
            futures_wait([self._future], timeout=wait_s)
        self._collect(wait=wait)
        if self._future is not None and self._future.cancel():  # queued, never started: it will tell ``early`` nothing
            if self._early is not None and self._offering and not self._history:
                self._early.release()  # the first window's search never ran: its head must not wait for it
            self._future = None
            self._abandoned += 1
        if self._future is not None:  # still running, not waited for: it stops at its next fit
            carry = self._budget is not None and self._early is not None and self._offering and not self._history
            if carry and self._carried is None:
                self._carried = self._stop  # set by _first_searched once the search has offered its model
                if self._early is not None and self._early.offered:  # it ended meanwhile: only its warm refit runs
                    self._stop.set()
                _unyield(self._niced)  # no sampler any more: the worker at its own priority
            else:
                self._stop.set()
            self._stop = threading.Event()  # a final refit runs on
            self._future = None
            self._abandoned += 1

    def result(
        self, *, final: bool = True, fresh_s: float = 0.0, wait: bool = True, wait_s: float = 0.0
    ) -> WindowResult:
        """Wait for a running refit; with ``final``, refit the last window too (the end of the stream); stop the worker.

        Parameters
        ----------
        final : bool
            Fit the window that ends at the last sample (when it is not the last refit's).
        fresh_s : float
            ... unless the last refit's window ended at most this many servo seconds before the
            stream's end (a live identify: :data:`EVERY_S`, the estimate as fresh as between two
            refits; the final refit cost 0.1-17 s of wall time after a real-clock run, issue 15); on a
            real clock also when a second look from the early search (``early``) is still due: that
            search is waited for (its caller waits for it next anyway) and the end refitted with it.
        wait : bool
            Wait for a refit still running; False (a live identify on a real clock): wait at most
            ``wait_s``, then tell it to stop at its next fit and drop it
            (:attr:`WindowResult.abandoned`): the newest finished window is the estimate. The final
            refit then runs on the worker only when no refit was dropped so, and is treated the same.
        wait_s : float
            With ``wait=False``: wall seconds to wait for each refit before it is stopped.
        """
        abandoned = self._abandoned
        self._bounded(wait, wait_s)
        if self._early is not None and not self._offering:
            self._early.release()  # no first window's search ran: none will be offered
        n = self._n
        last = self._history[-1].t_s if self._history else -math.inf
        end = n * self.config.sample_period_s
        stale = not math.isclose(last, end) and end - last > fresh_s
        if final and n >= self._first and stale and (wait or self._pool is None):
            pool, self._pool = self._pool, None
            self._due(n)
            self._pool = pool
        elif final and n >= self._first and (stale or self._look_pending(n)) and self._abandoned == abandoned:
            if self._early is not None and self._look_pending(n):  # (the caller waits for that search next anyway)
                self._early.result(wait=True)
            self._end = 0  # the end's own refit: not late by definition
            self._due(n)
            self._bounded(wait, wait_s)
        if self._pool is not None:
            self._pool.shutdown(wait=wait, cancel_futures=not wait)
            self._pool = None
            sys.setswitchinterval(self._switch)
        return WindowResult(self.model if self._history else None, tuple(self._history[-HISTORY_ROWS:]), self.config, self._dropped,
                            self._stall, tuple(self._errors), self._rival, self._search,
                            end_s=n * self.config.sample_period_s, late=self._late,
                            abandoned=self._abandoned, carried=self._carried is not None)  # fmt: skip
