"""What ``servoid emulate dxl`` and ``servoid emulate feetech`` share: the IDs option, the link, serving until Ctrl-C."""

from __future__ import annotations

import argparse
import os
import signal
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from servoid.cli._live import DEFAULT_RATE_HZ
from servoid.errors import ConfigError
from servoid.output_paths import new_link, remove_own_link

__all__ = [
    "ids_option", "print_event", "add_link_option", "add_rate_and_servo_options", "period_s", "priority_line", "serve",
]  # fmt: skip


def ids_option(max_id: int) -> Callable[[str], list[int]]:
    """The ``--ids`` parser for servo IDs 0..``max_id``.

    Parameters
    ----------
    max_id : int
        The highest ID the protocol allows.
    """

    def parse(text: str) -> list[int]:
        try:
            ids = [int(part) for part in text.replace(" ", "").split(",") if part]
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"--ids (={text!r}) must be servo IDs separated by commas, e.g. 1,2"
            ) from None
        if not ids or any(not 0 <= i <= max_id for i in ids) or len(set(ids)) != len(ids):
            raise argparse.ArgumentTypeError(f"--ids (={text!r}) must be distinct servo IDs in 0..{max_id}")
        return ids

    return parse


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def print_event(line: str) -> None:
    """A servo's own decision (watchdog, torque off), with the monotonic time a watching process can compare.

    Parameters
    ----------
    line : str
        What the servo did.
    """
    print(f"{line} (monotonic {time.monotonic():.6f} s)", flush=True)


def add_link_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--link PATH``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The kind's parser.
    """
    parser.add_argument("--link", type=Path, metavar="PATH",
                        help="also make PATH a symbolic link to the pseudo-terminal (a stable name for scripts); "
                             "PATH must not exist: nothing is replaced")  # fmt: skip


def add_rate_and_servo_options(parser: argparse.ArgumentParser, default_servo: str) -> None:
    """Add ``--rate HZ`` (the servos' own sample rate) and ``--servo NAME[?K=V&...]``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The kind's parser.
    default_servo : str
        The twin behind each ID by default.
    """
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ, metavar="HZ",
                        help=f"the servos' own sample rate, Hz: sample them at this rate (default {DEFAULT_RATE_HZ:g}, "
                             "that of servoid identify; 0: one sample per goal)")  # fmt: skip
    parser.add_argument("--servo", metavar="NAME[?K=V&...]",
                        help=f"the servo behind each ID: a twin preset with overrides, or model (default {default_servo})")  # fmt: skip


def period_s(rate_hz: float) -> float | None:
    """The servos' own sample period for ``--rate`` (None for 0: one sample per goal).

    Parameters
    ----------
    rate_hz : float
        The ``--rate`` given.
    """
    if not (rate_hz >= 0 and rate_hz < float("inf")):
        raise ConfigError(f"--rate (={rate_hz:g}) must be >= 0 Hz (0: one sample per goal)")
    return 1.0 / rate_hz if rate_hz else None


def priority_line(granted: bool) -> str:
    """The line an emulator from the command line prints about its real-time priority (:mod:`servoid.drivers.realtime`).

    Parameters
    ----------
    granted : bool
        Whether the system granted ``SCHED_FIFO`` (:func:`~servoid.drivers.realtime.make_realtime`).
    """
    from servoid.drivers.realtime import DEVICE_PRIORITY

    if granted:
        return f"real-time priority: SCHED_FIFO {DEVICE_PRIORITY} (the servos' clock ahead of the host's loop)"
    return ("real-time priority: not permitted here (root, CAP_SYS_NICE or an RLIMIT_RTPRIO of "
            f"{DEVICE_PRIORITY} grants it); running at normal priority, slots may be late on a busy host")  # fmt: skip


def serve(make: Callable[[], Any], link: Path | None, lines: Callable[[str], Sequence[str]]) -> int:
    """Build the emulator, print ``lines(port)``, serve until Ctrl-C or SIGTERM, then close it and remove the link.

    The process takes real-time priority first, where the system permits it, and keeps the garbage collector off
    the heap it serves with, as the emulators a live session starts do (:mod:`servoid.drivers.realtime`).

    Parameters
    ----------
    make : callable
        Builds the emulator (a :class:`~servoid.drivers._pty_bus.PtyBusEmulator`).
    link : Path or None
        A symbolic link to make to its pty.
    lines : callable
        The lines to print, given the port name to show (the link when there is one).
    """
    from servoid.drivers.realtime import collector_off_heap, make_realtime

    if link is not None:
        new_link(link, option="--link")
    granted = make_realtime()  # the servos' clock first, where permitted; before the emulator's threads
    emulator = make()
    try:
        if link is not None:
            os.symlink(emulator.port, link)
        for line in lines(str(link) if link is not None else emulator.port):
            print(line, flush=True)
        print(priority_line(granted), flush=True)
        print("serving until Ctrl-C", flush=True)
        # `kill` stops it as cleanly as Ctrl-C (a shell starts background jobs with Ctrl-C ignored)
        signal.signal(signal.SIGTERM, _interrupt)
        try:
            with collector_off_heap():  # a full collection would hold the servos' replies and their watchdog
                emulator.serve_forever()
        except KeyboardInterrupt:
            pass
        print(f"stopped: {emulator.stats.received} packets received, {emulator.stats.replies} answered", flush=True)
        return 0
    finally:
        emulator.close()
        if link is not None:
            remove_own_link(link, emulator.port)
