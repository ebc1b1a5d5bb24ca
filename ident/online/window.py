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
  places of the play, chosen by validation), unless a start is given (a model
  file's loop: the monitor); every later one is :func:`refit_loop` from the
  previous answer. The first :attr:`WindowConfig.burn_in_s` of each window are
  simulated, not scored: where in the play the motor side starts is unknown;
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
  refit inside :meth:`update` (replays, tests: deterministic).

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
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.models.servo_loop import ServoLoopModel

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
#: Refits :attr:`WindowResult.history` keeps (the last ones): a monitor refits for days, identify's
#: refits every 5 s fill it in 5.7 h.
HISTORY_ROWS = 4096


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
    reversals : int
        Reversals of the window's scored readings by more than twice the play the window's fit
        started from (:func:`~servoid.ident.offline.intervals.reversals`, identify's rule): each
        is the motor crossing the play, what the window says about it. -1: not counted.
    """

    t_s: float
    play: float
    nrmse: float
    floor: float
    seconds: float
    structure: str
    reversals: int = -1

    def to_dict(self) -> dict[str, Any]:
        """For JSON."""
        return {"t_s": self.t_s, "play": self.play, "nrmse": self.nrmse, "floor": self.floor,
                "seconds": self.seconds, "structure": self.structure, "reversals": self.reversals}  # fmt: skip


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
        The first fit's best model with the play in the other place (None when the run started
        from a given model): where the refinement of the whole record starts that place from.
    """

    model: ServoLoopModel | None
    history: tuple[WindowRow, ...]
    config: WindowConfig
    dropped: int
    stall_s: float
    errors: tuple[str, ...] = field(default=())
    rival: ServoLoopModel | None = None

    @property
    def plays(self) -> np.ndarray:
        """The play of each refit."""
        return np.array([r.play for r in self.history], dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """For JSON (the history as rows)."""
        return {"model": None if self.model is None else self.model.to_dict(),
                "history": [r.to_dict() for r in self.history], "config": self.config.to_dict(),
                "dropped": self.dropped, "stall_s": self.stall_s, "errors": list(self.errors)}  # fmt: skip


def _refit(
    u: np.ndarray,
    y: np.ndarray,
    keep: np.ndarray,
    start: ServoLoopModel | None,
    config: WindowConfig,
    t_s: float,
    later: LaterFit | None = None,
) -> tuple[ServoLoopModel, WindowRow, ServoLoopModel | None]:
    """Fit one window (the worker's job): from scratch with both places of the play, or warm from ``start``.

    ``later``: the fit to use instead of :func:`refit_loop` (``later(u, y, score, start)``).
    Returns the model, its row, and from the first fit the best model of the other place of
    the play (the rival the refinement of the whole record starts that place from; None after).
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
        choice = fit_loop(u, filled, config.sample_period_s)
        model = choice.model
        rival = next((c.model for c in choice.candidates if c.structure != choice.structure), None)
    else:
        model, rival = start, None
    turns = reversals(y[score], 2.0 * model.play)
    if later is not None:
        model, q = later(u, y, score, model)
    else:
        fit = refit_loop(u, y, model, score=score, max_nfev=config.max_nfev)
        model, q = fit.model, fit.fit_nrmse
    row = WindowRow(t_s, model.play, q, floor_nrmse(y[score]), time.perf_counter() - t0, model.structure, turns)
    return model, row, rival


def _yield_cpu() -> None:
    """Lower the worker thread's scheduling priority (Linux sets it per thread): on a busy machine the sampler goes first."""
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + WORKER_NICENESS))
    except (AttributeError, OSError):  # not Linux, or not permitted: the thread keeps its priority
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
    """

    def __init__(
        self,
        config: WindowConfig,
        *,
        start: ServoLoopModel | None = None,
        background: bool = True,
        wait: bool = False,
        later: LaterFit | None = None,
    ) -> None:
        if not isinstance(config, WindowConfig):
            raise ConfigError(f"config must be a WindowConfig, not {type(config).__name__}")
        if start is not None and not math.isclose(start.sample_period_s, config.sample_period_s, rel_tol=1e-6):
            raise ConfigError(f"the start model's period ({start.sample_period_s:g} s) is not the stream's "
                              f"({config.sample_period_s:g} s)")  # fmt: skip
        self.config = config
        self.model = start
        self._later = later
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
        self._pool = (
            ThreadPoolExecutor(max_workers=1, thread_name_prefix="servoid-window", initializer=_yield_cpu)
            if background
            else None
        )
        self._switch = sys.getswitchinterval()
        if background:
            sys.setswitchinterval(min(self._switch, SWITCH_INTERVAL_S))
        self._future: Future[tuple[ServoLoopModel, WindowRow, ServoLoopModel | None]] | None = None
        self._rival: ServoLoopModel | None = None
        self._wait = bool(wait)
        self._waited = 0.0  # of the current sample, on a virtual clock: not a stall of a real sampler

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
        size = len(self._u)
        first = not self._history and not self._gone
        lo = max(0, size - self._span())
        keep = np.array(self._keep[lo:], dtype=np.bool_)
        if not keep.any():
            return
        lo += int(np.argmax(keep))  # the simulation starts at a measured sample
        if size - lo < 4 * self.config.samples(self.config.burn_in_s) or int(np.sum(keep)) < 50:
            return
        job = (np.array(self._u[lo:]), np.array(self._y[lo:]), np.array(self._keep[lo:], dtype=np.bool_),
               self.model if first or self._later is None else self._held, self.config,
               n * self.config.sample_period_s, None if first else self._later)  # fmt: skip
        if self._pool is None:
            self._store(job)
        else:
            self._future = self._pool.submit(_refit, *job)

    def _store(self, job: tuple[Any, ...]) -> None:
        try:
            self._keep_fit(*_refit(*job))
        except (ConfigError, ValueError, FloatingPointError, OverflowError, np.linalg.LinAlgError) as exc:
            self._errors.append(f"window ending at {job[5]:.1f} s: {exc}")

    def _keep_fit(self, model: ServoLoopModel, row: WindowRow, rival: ServoLoopModel | None) -> None:
        self.model = model
        self._held = model if self._held is None else self._held
        self._rival = rival if rival is not None else self._rival
        self._history.append(row)
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

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the servo-loop simulation now, not inside the sampling loop."""
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
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
            sys.setswitchinterval(self._switch)

    def result(self, *, final: bool = True) -> WindowResult:
        """Wait for a running refit; with ``final``, refit the last window too (the end of the stream); stop the worker.

        Parameters
        ----------
        final : bool
            Fit the window that ends at the last sample (when it is not the last refit's).
        """
        self._collect(wait=True)
        n = self._n
        last = self._history[-1].t_s if self._history else -1.0
        if final and n >= self._first and not math.isclose(last, n * self.config.sample_period_s):
            pool, self._pool = self._pool, None
            self._due(n)
            self._pool = pool
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
            sys.setswitchinterval(self._switch)
        return WindowResult(self.model if self._history else None, tuple(self._history[-HISTORY_ROWS:]), self.config, self._dropped,
                            self._stall, tuple(self._errors), self._rival)  # fmt: skip
