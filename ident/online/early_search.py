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
from collections.abc import Mapping

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.online.window import SlowSearch, _yield_cpu

__all__ = ["EarlySearch", "HEAD_SHARE", "BEGIN_WAIT_S", "head_samples"]

#: Share of the fast part (the run after a design's slow phase) the early search covers; the rest
#: runs while it searches and joins the answer through the final refit. A quarter of a 40 s run's
#: fast part is 6.7 s of servo time, about what the search of the rest takes on this machine under load.
HEAD_SHARE = 0.75
#: Wall seconds :meth:`EarlySearch.searched` waits for the search to start (a guard: it has started when asked).
BEGIN_WAIT_S = 5.0


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
    """

    def __init__(self, sample_period_s: float, at: int, *, skip: int = 0, hold: bool = False) -> None:
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
        """Nothing to compile that the window refit has not (:meth:`~servoid.ident.online.window.WindowRefit.warm_up`)."""

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
        self._job = (u[lo:], y[lo:], keep[lo:], lo)
        if not self._hold:
            self.begin()
        self._begun.set()

    def begin(self) -> None:
        """Start a held search (``hold``) whose samples have all come; nothing otherwise (once)."""
        with self._lock:
            job, self._job = self._job, None
            if job is not None:
                self._thread = threading.Thread(target=self._search, args=job, name="servoid-early-search", daemon=True)
                self._thread.start()

    def _search(self, u: np.ndarray, y: np.ndarray, keep: np.ndarray, lo: int) -> None:
        from servoid.ident.offline.loop_fit import fit_loop

        _yield_cpu()
        try:
            choice = fit_loop(u, y, self.sample_period_s, keep=keep, load=None)
        except Exception as exc:  # noqa: BLE001 - the refinement then searches itself, and meets it there
            self.error = f"the early search failed: {exc}"
            return
        self._found = SlowSearch(choice, lo, int(u.size))

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
