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

The pool is made at the first use and kept (a Jacobian is computed some
hundred times per fit); it is remade when the rule's answer changes, dropped in
a forked child (its threads do not survive ``fork``), and its threads are
joined at interpreter exit by :mod:`concurrent.futures` itself.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import queue
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

from servoid.errors import ConfigError

__all__ = ["ENV", "threads", "one_thread", "pool", "each"]

#: The environment variable that sets the number of threads (a positive integer).
ENV = "SERVOID_THREADS"

# a context variable, not a global: a Dask worker with several threads runs each task in its own context
_ONE: contextvars.ContextVar[bool] = contextvars.ContextVar("servoid_one_thread", default=False)
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


def each(func: Callable[[int], None], count: int) -> None:
    """Call ``func(i)`` for every ``i < count``: on the calling thread and the pool's helpers, in any order.

    The calling thread takes tasks too, and a helper that has not started by the time the
    tasks are gone is cancelled, not waited for: on a busy machine a woken thread may wait
    milliseconds for a core (the same wait :func:`._oefit.single_threaded_blas` avoids), and the
    caller then simply does the work itself. ``func`` must write only its own part of any output.

    Parameters
    ----------
    func : callable
        Takes the task's index; its return value is ignored; an exception it raises is raised here.
    count : int
        The number of tasks.
    """
    helpers = pool() if count > 1 else None
    if helpers is None:
        for i in range(count):
            func(i)
        return
    tasks: queue.SimpleQueue[int] = queue.SimpleQueue()
    for i in range(count):
        tasks.put(i)

    def drain() -> None:
        while True:
            try:
                i = tasks.get_nowait()
            except queue.Empty:
                return
            func(i)

    started = [helpers.submit(drain) for _ in range(min(_size, count - 1))]
    try:
        drain()
    finally:
        for future in started:
            if not future.cancel():
                future.result()


def _forget_after_fork() -> None:
    global _pool, _size, _lock
    _pool, _size, _lock = None, 0, threading.Lock()  # the parent's lock may have been held by another thread


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)
