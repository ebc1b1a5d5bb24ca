"""The live answer's search, started before the run ends: the fast part's head searched off the sampling thread.

A live ``identify`` answers with the offline search on its record
(:func:`~servoid.ident.online.refinement.refine_online`:
:func:`~servoid.ident.offline.loop_fit.fit_loop` with the load stage). After
the run that search was the largest part of the wall time (5-50 s on this
shared machine after 60 s of servo time; issue 15's budget is 60 s for probe
and identification). It needs no sample after the part it searches, so
:class:`EarlySearch`, fed by the session like an estimator, buffers the
stream after the design's slow phase and, once :attr:`at` samples of it have
come (:data:`HEAD_SHARE` of the fast part, :func:`head_samples`), runs
``fit_loop(load=None)`` on them on a thread of its own while the run goes on.
The refinement then takes that search for the fast part's head and refits its
answer warm on the whole fast part (:data:`~servoid.ident.offline.loop_fit.FINAL_NFEV`
evaluations), as ``fit_loop`` itself searches a long record's first
:data:`~servoid.ident.offline.loop_fit.SEARCH_SAMPLES` and refits the winner on
all of it.

The thread is a daemon at a lower scheduling priority (the window refit's,
:data:`~servoid.ident.online.window.WORKER_NICENESS`): a run interrupted while
the search runs does not wait for it (the session has already switched the
torque off and closed the recording); :meth:`EarlySearch.result` without
``wait`` leaves it. A search that fails leaves no result, and the refinement
searches the whole fast part itself, as it does when the run ended before
:attr:`at` (too few samples).

The same class searches a live design's slow phase (``skip=0``, ``at`` the slow
phase's samples: :func:`~servoid.ident.offline.loop_fit.fit_loop`, ``load=None``,
on the slow phase from its first measured sample, as the window refit searched it
when a window first put the play outside the loop, and as the refinement's step 4
does), held (``hold``) until first asked for, by the first window that puts the play
outside the loop or else by the refinement, and handed to both
(:class:`~servoid.ident.online.window.WindowRefit`'s ``slow_early``,
:func:`~servoid.ident.online.refinement.refine_online`'s ``slow_search``): one search of
the slow phase instead of two, and not on the window refit's worker, whose windows go on
meanwhile. Held, not started at the slow phase's end: a search from there ran beside the
sampler through the fast part's first 10 s, which had been quiet, and the CAN emulators
over UDP lost more samples (unusable 0.17-0.44 of them on 8 runs at load 6.7-9.5, 7 refused
above 0.2; 0.10-0.19 on 5 runs without it at load 5.2-9.6, none refused; the loads differ).
Measured again with the kernels loaded before the run (docs/online.md, fourteenth pass): 4 of 8
UDP runs refused (21-26 % unusable) against 1 of 8 held, at a lower load.

On a slow machine the head's search is warm (``end``, a real clock's run; :meth:`EarlySearch.offer`):
``fit_loop(load=None)``'s load stage (its grid of inertia ratios and restitutions, refitted at each point)
was 21.7 of the 24.7 s the CiA 402 twin's head search took at load 6 (the massless search 1.4 s), and on a
loaded real clock that search took 22-64 s of wall time, ended up to 57 s after the run and put the
CiA 402 at 80-111 s (issue 15). The window refit's first window has run the same search, the load stage
included, on the fast part's first 10 s by then. Where that search kept a load with the play outside the
loop and the head's full search, predicted from its wall time scaled to the head's samples, would not
end within :data:`HEAD_LATE_S` of the run's end (or had not ended when the head's samples had all come),
the head is searched massless (``fit_loop(load=False)``) and the first window's model joins it as one more
candidate, refitted on the head's estimation blocks and judged on its validation blocks, as the refinement
judges the online estimate (:func:`~servoid.ident.online.refinement.refine_online`, steps 1-3): the
grid's search of a load is not run twice on the same servo. It answers only where that candidate wins and
names the place (the play outside the loop by at least
:data:`~servoid.ident.offline.intervals.MIN_STRUCTURE_MARGIN` in validation); else the head's full
search runs after all. A virtual clock (no ``end``) always runs the full search.

Where the first window's search had not ended when the head's samples had all come (:data:`TAKE_FIRST`),
the head is not searched at all: it waits for that search (carried past the run's end on a real clock,
:class:`~servoid.ident.online.window.WindowRefit`'s ``budget``) and takes it as its own, its choice on the
fast part's first 10 s, which the refinement then refits warm on the whole fast part. On the CiA 402 twin at
load 8-11 (docs/online.md, livecia22) the process gets about 15 s of CPU for the searches after the
sampler, and the three searches from scratch take 6.6-11 s each, 88-92 % of the fast part's in the load
stage: one fast-part search instead of two answered with the servo loop where main answered with the black box.

The window refit's second look (:class:`~servoid.ident.online.window.WindowRefit`,
``early=``) falls on the same samples (the fast part's first 20 s of a 26.7 s
fast part): it takes this search's answer (:meth:`EarlySearch.searched`)
instead of searching them again on its own worker. On a loaded real clock the
two searches of the same samples ran side by side and the look was abandoned
at the run's end (docs/online.md, "The online window's second look").
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import _threads
from servoid.ident.online.window import SlowSearch, _unyield, _yield_cpu

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.models.servo_loop import ServoLoopModel
    from servoid.ident.offline._threads import Stop
    from servoid.ident.offline.loop_fit import LoopChoice

__all__ = [
    "EarlySearch",
    "HEAD_SHARE",
    "BEGIN_WAIT_S",
    "HEAD_LATE_S",
    "OFFER_POLL_S",
    "TAKE_FIRST",
    "head_samples",
    "full_in_time",
]

#: Share of the fast part (the run after a design's slow phase) the early search covers; the rest
#: runs while it searches and joins the answer through the final refit. A quarter of a 40 s run's
#: fast part is 6.7 s of servo time, about what the search of the rest takes on this machine under load.
HEAD_SHARE = 0.75
#: Wall seconds :meth:`EarlySearch.searched` waits for the search to start (a guard: it has started when asked).
BEGIN_WAIT_S = 5.0
#: Wall seconds after the run's end by which the head's full search must be predicted to end for it to run
#: on a real clock (else it is searched warm from the first window's load, the module's text): issue 15's
#: 60 s leave about 14 s after the probe (6.2 s) and a 40 s run, of which the answer's refit and the
#: identification take 1-4 s.
HEAD_LATE_S = 8.0
#: Whether a real clock's head, when the first window's search has not ended by the time the head's samples have
#: all come (a slow machine), takes that search as its own instead of searching (livecia22, issue 15: the head's
#: search with its load stage is 10-11 s of CPU on the CiA 402 twin's live records, 88-92 % of it the load stage,
#: the first window's 6.6-8.9 s, the slow phase's 7 s; the process gets about 15 s of CPU for them at load 6-9).
TAKE_FIRST = True
#: Wall seconds between two looks at the stop while the head's search waits for the first window's offer
#: (:meth:`EarlySearch._await_offer`): how late past the wall budget's deadline such a wait is cut.
OFFER_POLL_S = 0.1


def full_in_time(first_s: float, first_samples: int, head: int, left_s: float) -> bool:
    """Whether the head's full search is predicted to end within :data:`HEAD_LATE_S` of the run's end.

    Predicted as the first window's search (``first_s`` wall seconds on ``first_samples``) scaled to the
    head's ``head`` samples, against ``left_s``, the servo seconds the run has left.
    """
    return first_s * head / max(first_samples, 1) <= left_s + HEAD_LATE_S


def head_samples(samples: int, slow: int, share: float = HEAD_SHARE) -> int:
    """Samples of the fast part the early search covers: ``share`` of the ``samples - slow`` after the slow phase.

    Parameters
    ----------
    samples : int
        Samples of the whole run.
    slow : int
        How many of them are the design's slow phase (0: none).
    share : float
        Share of the fast part searched early, in (0, 1].

    Returns
    -------
    int
        At least 1.
    """
    n = validation.integer("samples", samples, minimum=1)
    s = validation.integer("slow", slow, minimum=0)
    if not (math.isfinite(share) and 0.0 < share <= 1.0):
        raise ConfigError(f"share (={share:g}) must lie in (0, 1]")
    return max(1, int(share * max(n - s, 0)))


class EarlySearch:
    """An :class:`~servoid.ident.online.estimator.Estimator` that searches the fast part's head on a thread (module text).

    Parameters
    ----------
    sample_period_s : float
        The stream's period, s.
    at : int
        Samples after the slow phase at which the search starts, on those samples.
    skip : int
        How many of the stream's first samples are the design's slow phase (not searched here).
    hold : bool
        Keep the samples at ``at`` and start the search only when it is first asked for
        (:meth:`searched`, :meth:`begin`): the slow phase's search, which only a play outside
        the loop needs (the module's text).
    end : int
        Samples the stream will hold in all (a real clock's run): the head may then be searched
        warm from the first window's search (:meth:`offer`, the module's text); 0 (a virtual
        clock): always the full search.
    stop : Stop, optional
        The search's fits stop at it (:class:`~servoid.ident.offline._threads.Stop`: a live run's wall
        budget on a real clock); a search it stopped leaves no result and says so (:attr:`cut`).
    """

    def __init__(
        self,
        sample_period_s: float,
        at: int,
        *,
        skip: int = 0,
        hold: bool = False,
        end: int = 0,
        stop: Stop | None = None,
    ) -> None:
        self.sample_period_s = validation.positive("sample_period_s", sample_period_s)
        self.at = validation.integer("at", at, minimum=1)
        self._skip = validation.integer("skip", skip, minimum=0)
        self._seen = 0
        self._u: list[float] = []
        self._y: list[float] = []
        self._keep: list[bool] = []
        self._thread: threading.Thread | None = None
        self._due = False  # ``at`` reached: the search started, or could not (once either way)
        self._found: SlowSearch | None = None
        self._begun = threading.Event()  # set once ``at`` is reached (the search started or held, or could not)
        self._hold = bool(hold)
        self._job: tuple[np.ndarray, np.ndarray, np.ndarray, int] | None = None  # held: the samples, not yet searched
        self._lock = threading.Lock()  # begin() is called from the window's worker and the main thread
        self.error: str | None = None
        self._end = validation.integer("end", end, minimum=0)
        self._first: tuple[ServoLoopModel, float, int] | None = None  # the first window's model, wall s, samples
        self._offered = threading.Event()  # set by offer() or release(): nothing more will be offered
        self.warm = False  # the head was searched warm from the first window's model (the module's text)
        self._choice: LoopChoice | None = None  # the first window's search, as offered (TAKE_FIRST)
        self.taken = False  # the first window's search answered for the head (TAKE_FIRST)
        self._late = False  # the head's samples had all come before the first window's search was offered
        self._stop = stop
        self.cut = False  # the search was stopped by ``stop`` (:attr:`error` says so)
        self._yielding = True  # the search's thread runs below the sampler's priority (until :meth:`full_speed`)
        self._niced: tuple[int, int] | None = None  # that thread's id and niceness before, once lowered

    @property
    def started(self) -> bool:
        """Whether the search was started."""
        return self._thread is not None

    @property
    def ready(self) -> bool:
        """Whether ``at`` was reached with enough usable samples (the search started, or held to be started)."""
        return self._due and self.error is None

    def update(self, u: float, y: float) -> None:
        """Take a measured sample."""
        self._take(float(u), float(y), True)

    def skip(self, u: float) -> None:
        """Take a sample whose measurement is not to be used (its command still drives the simulation)."""
        self._take(float(u), math.nan, False)

    def warm_up(self) -> None:
        """Load the search's compiled kernels now, not on a worker beside the sampler: one :func:`fit_loop` with the
        load stage on a short simulated record.

        Loaded by the first search on a worker at niceness 10 (numba's cache: its data and the bitcode parsed), they
        held the sampler's thread: a live identify through the serial firmware, pinned to one core with a busy loop,
        was silent 1.06 s at the first window's refit, past the firmware's 0.5 s watchdog, with the modules already
        imported (:meth:`~servoid.ident.online.window.WindowRefit.warm_up`).
        """
        from servoid.ident.models.servo_loop import ServoLoopModel
        from servoid.ident.offline.loop_fit import fit_loop

        u = np.repeat(np.random.default_rng(0).uniform(-0.05, 0.05, 8), 50)
        model = ServoLoopModel("output_backlash", self.sample_period_s, kp=10.0, kv=50.0)
        fit_loop(u, model.simulate(u), self.sample_period_s, load=None)

    def current(self) -> Mapping[str, float]:
        """No estimate for progress lines (the window refit gives them)."""
        return {}

    def _take(self, u: float, y: float, keep: bool) -> None:
        self._seen += 1
        if self._seen <= self._skip or self._due:
            return
        self._u.append(u)
        self._y.append(y)
        self._keep.append(keep)
        if len(self._u) >= self.at:
            self._start()

    def _start(self) -> None:
        from servoid.ident.offline.loop_fit import MIN_SAMPLES

        self._due = True
        keep = np.array(self._keep, dtype=np.bool_)
        u, y = np.array(self._u), np.array(self._y)
        self._u, self._y, self._keep = [], [], []
        if int(keep.sum()) < MIN_SAMPLES:
            self.error = (
                f"{int(keep.sum())} usable samples of {keep.size} by the search's start (at least {MIN_SAMPLES})"
            )
            self._begun.set()
            return
        lo = int(np.argmax(keep))  # the simulation starts at a measured sample
        self._late = not self._offered.is_set()  # the first window's search had not ended (TAKE_FIRST)
        self._job = (u[lo:], y[lo:], keep[lo:], lo)
        if not self._hold:
            self.begin()
        self._begun.set()

    def offer(self, model: ServoLoopModel, seconds: float, samples: int, choice: LoopChoice | None = None) -> None:
        """The window refit's first window: its search's model, the search's wall seconds and its samples, and the
        search itself (``choice``, :data:`TAKE_FIRST`) (once)."""
        if not self._offered.is_set():
            self._first = (model, float(seconds), int(samples))
            self._choice = choice
            self._offered.set()

    @property
    def offered(self) -> bool:
        """Whether the first window's search was offered, or none will be (:meth:`release`)."""
        return self._offered.is_set()

    def release(self) -> None:
        """No first window will be offered (the stream ended): a search waiting for one runs in full."""
        self._offered.set()

    def begin(self) -> None:
        """Start a held search (``hold``) whose samples have all come; nothing otherwise (once)."""
        with self._lock:
            job, self._job = self._job, None
            if job is not None:
                self._thread = threading.Thread(target=self._search, args=job, name="servoid-early-search", daemon=True)
                self._thread.start()

    def full_speed(self) -> None:
        """The sampler has ended: the search's thread, running or to come, back at its own scheduling priority.

        Below the sampler's (:data:`~servoid.ident.online.window.WORKER_NICENESS`) while the run goes on; after it,
        that priority only lends the cores to the machine's other processes: on the CiA 402 twin at load 7-9 the
        slow phase's search, started at the run's end, had 1.3 s of CPU in the 9.6 s left to it (docs/online.md,
        fourteenth pass). Where raising a priority is not permitted the thread keeps the lower one.
        """
        with self._lock:
            self._yielding = False
            niced, self._niced = self._niced, None
        _unyield(niced)

    def _search(self, u: np.ndarray, y: np.ndarray, keep: np.ndarray, lo: int) -> None:
        from servoid.ident.offline.loop_fit import fit_loop

        with self._lock:
            if self._yielding:
                self._niced = _yield_cpu()
        try:
            with _threads.stopping(self._stop):
                taken = self._first_taken()
                if taken is not None:  # a slow machine: the first window's search answers for the head
                    self._found = SlowSearch(taken[0], lo, taken[1])
                    return
                choice = self._warm(u, y, keep)
                if choice is None:
                    choice = fit_loop(u, y, self.sample_period_s, keep=keep, load=None)
        except _threads.Stopped as exc:
            self.cut, self.error = True, f"the early search was cut: {exc}"
            return
        except Exception as exc:  # noqa: BLE001 - the refinement then searches itself, and meets it there
            self.error = f"the early search failed: {exc}"
            return
        self._found = SlowSearch(choice, lo, int(u.size))

    def _first_taken(self) -> tuple[LoopChoice, int] | None:
        """The first window's search and its samples as the head's search, or None (:data:`TAKE_FIRST`).

        Only on a real clock (``end``) where that search had not ended when the head's samples had all come (a slow
        machine): the head is then not searched at all, nor massless meanwhile; it waits for that search (under the
        stop) and takes it. Released with none (the search failed or was stopped), None: the head's own search runs.
        """
        if not (TAKE_FIRST and self._end and self._late):
            return None
        self._await_offer()
        if self._choice is None or self._first is None:
            return None
        self.taken = True
        return self._choice, self._first[2]

    def _warm(self, u: np.ndarray, y: np.ndarray, keep: np.ndarray) -> LoopChoice | None:
        """The head searched warm from the first window's model (the module's text), or None: the full search runs."""
        from servoid.ident.offline.intervals import MIN_STRUCTURE_MARGIN
        from servoid.ident.offline.loop_fit import fit_loop
        from servoid.ident.online.refinement import _refine

        if not self._end:
            return None
        t0 = time.perf_counter()
        massless = None
        if not self._offered.is_set():
            # the first window's search has not ended by now: a slow machine; the massless head meanwhile
            massless = fit_loop(u, y, self.sample_period_s, keep=keep, load=False)
            self._await_offer()
        elif self._first is not None and full_in_time(
            self._first[1], self._first[2], int(u.size), (self._end - self._seen) * self.sample_period_s
        ):
            return None
        first = None if self._first is None else self._first[0]
        if first is None or first.structure == PLAY_IN_LOOP or not first.massive:
            return None  # no load found by the first window's search: the grid runs here
        if massless is None:
            massless = fit_loop(u, y, self.sample_period_s, keep=keep, load=False)
        filled = np.where(keep, y, y[int(np.argmax(keep))])
        choice, refined = _refine(u, filled, keep, first, self.sample_period_s, t0, massless)
        if not (refined.online_won and choice.structure != PLAY_IN_LOOP and choice.margin >= MIN_STRUCTURE_MARGIN):
            return None  # the first window's load did not name the place on the head: the full search decides
        self.warm = True
        return choice

    def _await_offer(self) -> None:
        """Wait for the first window's search to offer its model or for :meth:`release`; under a stop (the wall
        budget), only until it comes: the wait is then cut as a search is (:class:`~servoid.ident.offline._threads.Stopped`).

        The window refit offers or releases on every way out of that search (livebus20's fix, issue 15); this
        keeps a head that waits from outliving the budget on a way that was missed. Without a stop it waits as
        before (a virtual clock never gets here: no ``end``).
        """
        while not self._offered.wait(OFFER_POLL_S if self._stop is not None else None):
            _threads.check()

    def searched(self, *, wait: bool) -> SlowSearch | None:
        """The search for the window refit's second look (called on its worker thread), or None.

        ``wait`` (a virtual clock, where waiting costs no sample): wait for the search to start
        (:data:`BEGIN_WAIT_S` at most: a session feeds this estimator before the window refit, so
        it has started by the time the window's look runs) and to end. Else the search only if it
        has ended: on a real clock the look is left to a later window rather than held up.
        A held search (``hold``) whose samples have all come is started here.
        """
        if wait and not self._begun.wait(BEGIN_WAIT_S):
            return None
        self.begin()
        return self.result(wait=wait)

    def result(self, *, wait: bool = True) -> SlowSearch | None:
        """The search of the fast part's head (``start``: its first sample after the slow phase), or None.

        None when it did not start (the run ended before :attr:`at`, too few usable samples), failed
        (:attr:`error`), or still runs and ``wait`` is False.
        """
        thread = self._thread
        if thread is not None and wait:
            thread.join()
        return self._found
