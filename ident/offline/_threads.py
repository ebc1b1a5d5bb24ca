"""How many threads a fit may use for independent simulations, and the one pool that runs them.

The servo-loop fit's forward-difference Jacobian runs one simulation per free
parameter; the compiled kernel releases the GIL (``nogil=True`` in
:mod:`servoid.ident._jit`), so on several cores the columns run at once.

The rule, first match wins:

1. inside :func:`one_thread` (``servoid batch`` wraps each record in it: its
   Dask workers already run one record per core, and threads on top would
   only oversubscribe the fleet), 1;
2. the environment variable ``SERVOID_THREADS`` (a positive integer), the
   user's override;
3. the CPUs this process may run on (``os.sched_getaffinity``, else
   ``os.cpu_count()``).

A whole fit whose inputs are known before the work it waits behind can start early on a thread of
its own (:class:`Ahead`, by the same rule: not where it gives one thread); the call that starts it
is wrapped in :func:`joins_ahead`, so no such thread outlives it.

A fit can be stopped (:class:`Stop`: a wall-time deadline, or told to): inside :func:`stopping` every
evaluation of a fit's cost (:func:`check`, from ``loop_fit._Problem.scored``) raises :class:`Stopped`
once the stop has come, on the calling thread, on an :class:`Ahead` job's thread (which runs in a copy
of the caller's context) and on the pool's helpers running an :func:`each` call's tasks (each task
runs under the stop of the call's owner). The search unwinds from there to whoever set the stop, who
keeps the best answer it already has. Outside :func:`stopping` nothing is checked: an offline fit
runs as it did, to the bit.

The pool is made at the first use and kept (a Jacobian is computed some
hundred times per fit); it is remade when the rule's answer changes, dropped in
a forked child (its threads do not survive ``fork``), and its threads are
joined at interpreter exit by :mod:`concurrent.futures` itself.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import math
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Generic, ParamSpec, TypeVar

from servoid.errors import ConfigError

__all__ = [
    "ENV", "threads", "one_thread", "pool", "each", "Ahead", "joins_ahead", "Stop", "Stopped", "stopping", "check",
]  # fmt: skip

P = ParamSpec("P")
R = TypeVar("R")

#: The environment variable that sets the number of threads (a positive integer).
ENV = "SERVOID_THREADS"

# a context variable, not a global: a Dask worker with several threads runs each task in its own context
_ONE: contextvars.ContextVar[bool] = contextvars.ContextVar("servoid_one_thread", default=False)
# the :class:`Ahead` jobs started inside the innermost :func:`joins_ahead` call (None outside one)
_STARTED: contextvars.ContextVar[list[Ahead[object]] | None] = contextvars.ContextVar("servoid_ahead", default=None)
# the stop the fits on this thread answer to (None: never stopped; :func:`stopping`)
_STOP: contextvars.ContextVar[Stop | None] = contextvars.ContextVar("servoid_stop", default=None)
_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None
_size = 0


def threads() -> int:
    """The number of threads the rule above gives here and now."""
    if _ONE.get():
        return 1
    text = os.environ.get(ENV, "").strip()
    if text:
        try:
            n = int(text)
        except ValueError:
            n = 0
        if n < 1:
            raise ConfigError(f"{ENV}={text!r} is not a positive integer (the threads a fit may use)")
        return n
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Run fits inside the block on the calling thread only (a worker that already runs one record per core)."""
    token = _ONE.set(True)
    try:
        yield
    finally:
        _ONE.reset(token)


def pool() -> ThreadPoolExecutor | None:
    """The shared pool of ``threads() - 1`` helpers (the caller is the other thread), or None for one thread."""
    global _pool, _size
    n = threads() - 1
    if n < 1:
        return None
    with _lock:
        if _pool is None or _size != n:
            old = _pool
            _pool, _size = ThreadPoolExecutor(max_workers=n, thread_name_prefix="servoid-fit"), n
            if old is not None:
                old.shutdown(wait=False)
        return _pool


class Stopped(Exception):
    """A fit stopped by its :class:`Stop` where it evaluated its cost; the search unwound (the message says why)."""


class Stop:
    """When the fits run inside :func:`stopping` stop: at a wall-time deadline, or when told to (:meth:`now`).

    One owner makes it and decides (the deadline, :meth:`now`); the fits only read it (:func:`check`,
    from any thread). It remembers whether it stopped a fit (:attr:`fired`), for the owner's report.

    Parameters
    ----------
    deadline_s : float
        The :func:`time.perf_counter` instant at which the fits stop (default never).
    why : str
        What the deadline is, said in :class:`Stopped`'s message (``"the wall budget"``).
    event : threading.Event, optional
        Stop when it is set too (a worker's own stop flag), besides :meth:`now`.
    """

    def __init__(
        self, deadline_s: float = math.inf, why: str = "the deadline", *, event: threading.Event | None = None
    ) -> None:
        if math.isnan(deadline_s):
            raise ConfigError("deadline_s is NaN (expected a time.perf_counter instant, or inf for none)")
        self.deadline_s = float(deadline_s)
        self.why = why
        self._event = threading.Event() if event is None else event
        #: Whether a fit was stopped by it (:func:`check` raised).
        self.fired = False

    def now(self) -> None:
        """Stop the fits at their next evaluation, whatever the deadline."""
        self._event.set()

    def left_s(self) -> float:
        """Wall seconds to the deadline (negative past it; infinite without one)."""
        return self.deadline_s - time.perf_counter()

    def passed(self) -> bool:
        """Whether the fits are to stop (the deadline passed, or told to)."""
        return self._event.is_set() or time.perf_counter() >= self.deadline_s

    def check(self) -> None:
        """Raise :class:`Stopped` when :meth:`passed`."""
        if self.passed():
            self.fired = True
            raise Stopped(f"stopped by {self.why}" if self._event.is_set() else f"stopped at {self.why}'s deadline")


@contextlib.contextmanager
def stopping(stop: Stop | None) -> Iterator[Stop | None]:
    """Run the fits inside the block under ``stop`` (None: not stopped; an outer stop is replaced for the block)."""
    token = _STOP.set(stop)
    try:
        yield stop
    finally:
        _STOP.reset(token)


def check() -> None:
    """Raise :class:`Stopped` when this thread's fits are to stop (:func:`stopping`); nothing outside one."""
    stop = _STOP.get()
    if stop is not None:
        stop.check()


class _Batch:
    """The tasks of one :func:`each` call: the indices not yet taken, the count not yet done, the first error."""

    def __init__(self, func: Callable[[int], None], count: int) -> None:
        self.func = func
        self.owner = threading.get_ident()
        self.tasks: queue.SimpleQueue[int] = queue.SimpleQueue()
        for i in range(count):
            self.tasks.put(i)
        self.left = count
        self.error: BaseException | None = None
        self.stop = _STOP.get()  # every task runs under the owner's stop, on whichever thread takes it

    def take(self) -> int | None:
        try:
            return self.tasks.get_nowait()
        except queue.Empty:
            return None

    def run(self, i: int) -> None:
        """Task ``i``; its error is kept for the owner, and its end counted (under :data:`_changed`)."""
        token = _STOP.set(self.stop)
        try:
            self.func(i)
        except BaseException as exc:  # noqa: BLE001 - raised by the owner, once every task has ended
            error: BaseException | None = exc
        else:
            error = None
        finally:
            _STOP.reset(token)
        with _changed:
            if error is not None and self.error is None:
                self.error = error
            self.left -= 1
            if self.left == 0:
                _changed.notify_all()

    def drain(self) -> None:
        while (i := self.take()) is not None:
            self.run(i)


# every :func:`each` call's batch while it has tasks not done; a change (a batch opened, a batch done) is notified
_changed = threading.Condition()
_open: list[_Batch] = []


def _lent(me: int) -> tuple[_Batch, int] | None:
    """A task of a batch another thread opened, for a thread that waits for its own batch (``_changed`` held)."""
    for batch in _open:
        if batch.owner != me and (i := batch.take()) is not None:
            return batch, i
    return None


def each(func: Callable[[int], None], count: int) -> None:
    """Call ``func(i)`` for every ``i < count``: on the calling thread and the pool's helpers, in any order.

    The calling thread takes tasks too, and a helper that has not started by the time the
    tasks are gone is cancelled, not waited for: on a busy machine a woken thread may wait
    milliseconds for a core (the same wait :func:`._oefit.single_threaded_blas` avoids), and the
    caller then simply does the work itself. A caller whose own tasks are all taken but not all
    done runs tasks of the other threads' calls meanwhile (never its own outer calls', which could
    hold it up): when the two places of the play are searched at once and one ends first, its
    thread computes Jacobian columns of the other instead of waiting for it. ``func`` must write
    only its own part of any output.

    Parameters
    ----------
    func : callable
        Takes the task's index; its return value is ignored; an exception it raises is raised here
        (the first, once every task has ended).
    count : int
        The number of tasks.
    """
    helpers = pool() if count > 1 else None
    if helpers is None:
        for i in range(count):
            func(i)
        return
    batch = _Batch(func, count)
    me = batch.owner
    with _changed:
        _open.append(batch)
        _changed.notify_all()
    started = [helpers.submit(batch.drain) for _ in range(min(_size, count - 1))]
    try:
        batch.drain()
        while True:
            with _changed:
                if batch.left == 0:
                    break
                lent = _lent(me)
                if lent is None:
                    _changed.wait()
                    continue
            lent[0].run(lent[1])
    finally:
        with _changed:
            _open.remove(batch)
        for future in started:
            future.cancel()  # a helper that started drains only what is left, and its tasks are counted above
    if batch.error is not None:
        raise batch.error


class Ahead(Generic[R]):
    """``func()`` started now on a thread of its own, its value (or its exception) given by :meth:`result`.

    Where :func:`threads` gives one thread it does not start: :meth:`result` calls ``func`` then,
    where the caller would have. The thread runs in a copy of the caller's context (so
    :func:`one_thread` reaches it) and joins the pool's helpers for its own parallel work; two
    threads compute while the caller works on, which on two cores is the point. ``func`` must
    only read what the caller may still change (pass it copies). Inside :func:`joins_ahead` the
    job is joined when that call ends, however it ends.

    Parameters
    ----------
    func : callable
        Takes no arguments.
    """

    def __init__(self, func: Callable[[], R]) -> None:
        self._func = func
        self._value: R | None = None
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        if threads() > 1:
            self._thread = threading.Thread(
                target=contextvars.copy_context().run, args=(self._run,), name="servoid-ahead", daemon=True
            )
            started = _STARTED.get()
            if started is not None:
                started.append(self)  # type: ignore[arg-type]
            self._thread.start()

    def _run(self) -> None:
        try:
            self._value = self._func()
        except BaseException as exc:  # noqa: BLE001 - raised again by result(), in the caller's thread
            self._error = exc

    def join(self) -> None:
        """Wait until the job has ended (at once when it never started)."""
        if self._thread is not None:
            self._thread.join()

    def result(self) -> R:
        """``func()``'s value, waited for; the exception it raised is raised here."""
        if self._thread is None:
            return self._func()
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._value  # type: ignore[return-value]


def joins_ahead(func: Callable[P, R]) -> Callable[P, R]:
    """``func`` that joins every :class:`Ahead` job it started before it returns or raises."""

    @functools.wraps(func)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        started: list[Ahead[object]] = []
        token = _STARTED.set(started)
        try:
            return func(*args, **kwargs)
        finally:
            _STARTED.reset(token)
            for job in started:
                job.join()

    return run


def _forget_after_fork() -> None:
    global _pool, _size, _lock, _changed, _open
    _pool, _size, _lock = None, 0, threading.Lock()  # the parent's lock may have been held by another thread
    _changed, _open = threading.Condition(), []


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)
