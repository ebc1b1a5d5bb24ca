"""Real-time scheduling for the thread that keeps a servo's clock: the host's sampling loop, an emulated device.

On a loaded host the scheduler, not the link, spoils the slots: on this
2-core machine at load 4.3-6.5, a 10 s ``run_session`` at 200 Hz against each
emulator (``benchmarks/twins.py``'s ``LIVE``) had 5-16 % of its slots late
and 6-13 % missed; with the sampling thread and the emulators at
``SCHED_FIFO`` 0-0.9 % and 0-0.4 % (``chrt -f 10`` on the same command, the
same minute). A missed or late slot is a lost sample, and on a device on its
own clock it opens a guard window (:data:`servoid.session.samples.DEFAULT_GUARD_SAMPLES`),
so 10 % missed slots left 60-91 % of a run unusable and ``identify`` refused it.

So a thread that keeps a clock asks for ``SCHED_FIFO`` where the operating
system grants it (Linux as root, with ``CAP_SYS_NICE``, or an ``RLIMIT_RTPRIO``
of at least the priority) and otherwise runs as before; the caller records
which. ``SCHED_RESET_ON_FORK`` keeps the priority from passing to the threads
and processes the holder starts (a worker thread, an emulator). The sampling
loop sleeps between slots and spins only the last ``MonotonicClock.spin_s``
(300 us of a 5 ms period), and the SDK ports wait in ``select``: the thread
leaves the core free most of the time, and the kernel's real-time throttling
(95 % of a core by default) bounds the rest.

``SCHED_FIFO`` does not reach the interpreter lock. A cyclic garbage collection
holds it from start to end, whichever thread set it off, and takes time in
proportion to the whole heap: 48-67 ms at ``SCHED_FIFO`` on the 153 000 objects a
live identify starts with (load 8), more in a larger process. Set off in a thread
the scheduler does not favour (rich's progress refresh at niceness 0, a refit's
worker at 10), it ran about as long as the scheduler gave that thread the core, and
the sampler waited behind it for the lock: one sleep of the sampler came back 391 ms
late, every thread's stack showing the collection (a live identify through the
Dynamixel emulator, pinned to one core with a busy process, load 7.8). Such a
wait past 0.5 s trips the Dynamixel's Bus Watchdog (issue 15): a collection set
off 1 s into that run on a 755 000-object heap tripped it 3 of 3 times, and 0 of
3 with the heap kept off (docs/drivers.md, "The garbage collector"). So a session
on the real clock keeps the collector off the heap it started with
(:func:`collector_off_heap`, ``gc.freeze``): a collection then looks only at the
objects made since, and the heap is handed back to the collector afterwards.
"""

from __future__ import annotations

import contextlib
import gc
import os
import threading
from collections.abc import Iterator

__all__ = ["SAMPLER_PRIORITY", "DEVICE_PRIORITY", "realtime_thread", "make_realtime", "collector_off_heap"]

#: ``SCHED_FIFO`` priority of the host's sampling thread (1-99; low: above every ordinary thread, below the
#: kernel's own real-time threads).
SAMPLER_PRIORITY = 10
#: ``SCHED_FIFO`` priority of an emulated device's process: above the host, as a device's own processor
#: is never held up by the host's work.
DEVICE_PRIORITY = SAMPLER_PRIORITY + 1


def _set_fifo(pid: int, priority: int, *, reset_on_fork: bool) -> bool:
    """``SCHED_FIFO`` at ``priority`` for ``pid`` (0: the calling thread); whether the system granted it."""
    if not hasattr(os, "SCHED_FIFO"):  # not Linux or a BSD: no real-time policy to ask for
        return False
    policy = os.SCHED_FIFO | (os.SCHED_RESET_ON_FORK if reset_on_fork else 0)
    try:
        os.sched_setscheduler(pid, policy, os.sched_param(priority))
    except OSError:  # not permitted (EPERM), or the process is gone
        return False
    return True


@contextlib.contextmanager
def realtime_thread(priority: int = SAMPLER_PRIORITY) -> Iterator[bool]:
    """The calling thread at ``SCHED_FIFO`` while inside, when permitted; yields whether it is.

    Its policy and priority before are restored on leaving. Threads and
    processes it starts meanwhile do not inherit the policy.

    Parameters
    ----------
    priority : int
        ``SCHED_FIFO`` priority, 1-99.
    """
    if not hasattr(os, "SCHED_FIFO"):
        yield False
        return
    before, param = os.sched_getscheduler(0), os.sched_getparam(0)
    granted = _set_fifo(0, priority, reset_on_fork=True)
    try:
        yield granted
    finally:
        if granted:
            with contextlib.suppress(OSError):
                os.sched_setscheduler(0, before, param)


def make_realtime(pid: int = 0, priority: int = DEVICE_PRIORITY) -> bool:
    """Put a whole emulated device's process at ``SCHED_FIFO`` for good, when permitted; whether it is.

    Its threads started afterwards inherit the policy (the device's timer and
    its link's reader alike).

    Parameters
    ----------
    pid : int
        The process (0: the calling one, from its main thread before it starts others).
    priority : int
        ``SCHED_FIFO`` priority, 1-99.
    """
    return _set_fifo(pid, priority, reset_on_fork=False)


_frozen_lock = threading.Lock()
_frozen_holders = 0


@contextlib.contextmanager
def collector_off_heap() -> Iterator[None]:
    """The garbage collector kept off the objects that exist on entry, while inside (the module's text).

    ``gc.freeze`` on the first entry, ``gc.unfreeze`` on the last exit (sessions
    in several threads share one heap); their garbage is collected after.
    """
    global _frozen_holders
    with _frozen_lock:
        if _frozen_holders == 0:
            gc.freeze()
        _frozen_holders += 1
    try:
        yield
    finally:
        with _frozen_lock:
            _frozen_holders -= 1
            if _frozen_holders == 0:
                gc.unfreeze()
