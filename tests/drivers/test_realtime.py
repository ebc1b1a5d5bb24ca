"""Real-time scheduling of the sampling loop and of the emulated devices (``servoid.drivers.realtime``).

A session on the real clock also keeps the garbage collector off the heap it
started with (a full collection in any thread holds the interpreter lock the
loop needs), hands it back afterwards, and no progress thread runs beside the
loop: off a terminal no bar is built, on one the loop's progress call draws it.

A live session's loop runs at ``SCHED_FIFO`` where the system permits it
(and says so in ``acquisition.realtime``), gives the policy back afterwards,
does not pass it to the threads it starts, and does not take it on a
virtual clock (where it would run flat out). Each emulator's device process
(the C firmware, the Dynamixel emulator, ``servoid emulate can``) runs at
``SCHED_FIFO`` where permitted. The real drivers and libraries run against
the emulators; whether the system permits it is asked the way the code asks
it, and a test of the other case says so when it cannot run here.
"""

from __future__ import annotations

import gc
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from servoid.cli._live import check_lost
from servoid.drivers import driver_from_url
from servoid.drivers.realtime import DEVICE_PRIORITY, SAMPLER_PRIORITY, collector_off_heap, realtime_thread
from servoid.errors import ConfigError
from servoid.session import SessionConfig, run_session

pytestmark = pytest.mark.skipif(not hasattr(os, "SCHED_FIFO"), reason="no real-time scheduling policy here")

RATE_HZ = 200.0


def _permitted() -> bool:
    """Whether this thread may take SCHED_FIFO (asked, then given back)."""
    with realtime_thread() as granted:
        return granted


def _policy(pid: int = 0) -> int:
    return os.sched_getscheduler(pid) & ~os.SCHED_RESET_ON_FORK


def _session_policies(
    url: str, command_filter: Callable[[float], float] | None = None
) -> tuple[Any, list[int], list[int]]:
    """A short session: its result, the sampling thread's policy per sample, a started thread's policy."""
    seen: list[int] = []
    started: list[int] = []

    def on_sample(sample: object) -> None:  # noqa: ARG001 - run_session's on_sample signature
        seen.append(_policy())
        if not started:  # a worker started from the loop, as the window refit's pool is
            worker = threading.Thread(target=lambda: started.append(_policy()))
            worker.start()
            worker.join()

    u = 0.05 * np.sin(2 * np.pi * np.arange(100) / 50)
    with driver_from_url(url) as servo:
        result = run_session(
            servo, u, SessionConfig(period_s=1 / RATE_HZ), on_sample=on_sample, command_filter=command_filter
        )
    return result, seen, started


@pytest.fixture
def firmware_url() -> Iterator[tuple[str, int]]:
    from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions

    with FirmwareEmulator(FirmwareOptions(servo="xm430")) as emu:
        assert emu.process is not None
        yield emu.url, emu.process.pid


def test_session_samples_at_fifo_and_gives_it_back(firmware_url: tuple[str, int]) -> None:
    url, _ = firmware_url
    before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    result, seen, started = _session_policies(url)
    acquisition = result.to_dict()
    if _permitted():
        assert acquisition["realtime"] is True
        assert set(seen) == {os.SCHED_FIFO}
        assert os.sched_getparam(0).sched_priority == before[1]  # given back
    else:
        assert acquisition["realtime"] is False
        assert os.SCHED_FIFO not in seen
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    assert started == [before[0] & ~os.SCHED_RESET_ON_FORK]  # the policy before, not the loop's


def test_virtual_clock_session_does_not_take_fifo() -> None:
    result, seen, _ = _session_policies("sim://model?clock=virtual")
    acquisition = result.to_dict()
    assert acquisition["realtime"] is False
    assert os.SCHED_FIFO not in seen


def test_a_real_clock_session_keeps_the_collector_off_the_heap_it_started_with() -> None:
    before = gc.get_freeze_count()
    frozen: dict[str, list[int]] = {"sim://model": [], "sim://model?clock=virtual": []}
    for url, seen in frozen.items():
        with driver_from_url(url) as servo:
            run_session(servo, np.zeros(20), SessionConfig(period_s=1 / RATE_HZ),
                        on_sample=lambda _, seen=seen: seen.append(gc.get_freeze_count()))  # fmt: skip
    assert min(frozen["sim://model"]) > before  # the objects of before the session: never scanned during it
    assert frozen["sim://model?clock=virtual"] == [before] * 20  # no time to keep: as before
    assert gc.get_freeze_count() == before  # handed back
    with collector_off_heap():  # sessions in two threads: the heap is handed back when the last one ends
        held = gc.get_freeze_count()
        with collector_off_heap():
            pass
        assert gc.get_freeze_count() == held > before
    assert gc.get_freeze_count() == before


def test_no_progress_thread_beside_the_loop_when_stderr_is_not_a_terminal(capsys: pytest.CaptureFixture[str]) -> None:
    from servoid.cli import _term

    threads = set(threading.enumerate())
    with _term.live_progress("live", 10) as update:
        update(5, "half")
        assert set(threading.enumerate()) == threads
    assert capsys.readouterr().err == ""


def test_on_a_terminal_the_bar_is_drawn_by_its_caller_with_no_thread_beside_the_loop(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import io

    from rich.console import Console

    from servoid.cli import _term

    screen = io.StringIO()
    monkeypatch.setattr(_term, "stderr", Console(file=screen, force_terminal=True, width=100), raising=False)
    threads = set(threading.enumerate())
    with _term.live_progress("live", 10) as update:
        assert set(threading.enumerate()) == threads  # no refresh thread of rich's
        update(5, "half way")
        assert "half way" in screen.getvalue() and "5/10" in screen.getvalue()  # drawn by the call itself


def test_not_permitted_runs_as_before(monkeypatch: pytest.MonkeyPatch, firmware_url: tuple[str, int]) -> None:
    # the system's refusal (EPERM, as for a user without CAP_SYS_NICE or RLIMIT_RTPRIO), not a stand-in driver
    def refuse(pid: int, policy: int, param: os.sched_param) -> None:  # noqa: ARG001 - os.sched_setscheduler's
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    stalls = iter(range(10**6))

    def stall(u: float) -> float:  # every 20th slot's command comes 3 ms late: a host that was busy
        if next(stalls) % 20 == 19:
            time.sleep(3e-3)
        return u

    result, seen, _ = _session_policies(firmware_url[0], stall)
    assert result.to_dict()["realtime"] is False
    assert os.SCHED_FIFO not in seen
    assert result.counts["late"] + result.counts["missed"] >= 4
    # the refusal names the cause a user can remove
    with pytest.raises(ConfigError, match="without real-time priority") as refused:
        check_lost(result, 0.0, allow=False, path=Path("recording.csv"))
    assert len(str(refused.value).splitlines()) == 1


def _expect_device_fifo(pid: int) -> None:
    if not _permitted():
        pytest.skip("SCHED_FIFO is not permitted here: the emulators run as before")
    assert _policy(pid) == os.SCHED_FIFO
    assert os.sched_getparam(pid).sched_priority == DEVICE_PRIORITY > SAMPLER_PRIORITY


def test_firmware_runs_at_fifo(firmware_url: tuple[str, int]) -> None:
    _expect_device_fifo(firmware_url[1])


def test_dynamixel_emulator_runs_at_fifo() -> None:
    from servoid.drivers.dynamixel.emulator import EmulatorProcess

    with EmulatorProcess([1], period_s=1 / RATE_HZ, servo="xm430") as emu:
        assert emu._process is not None
        _expect_device_fifo(emu._process.pid)
        # the real SDK against it still answers (dynamixel-sdk on the pty)
        result, _, _ = _session_policies(emu.url(1))
        assert result.counts["ok"] > 0


def test_can_emulator_runs_at_fifo() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        port = s.getsockname()[1]
    cmd = [sys.executable, "-m", "servoid", "emulate", "can", "--protocol", "odrive", "--port", str(port),
           "--rate", f"{RATE_HZ:g}", "--servo", "odrive", "--quiet"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip() if proc.stdout else ""
        assert url.startswith("can://"), url
        _expect_device_fifo(proc.pid)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=10)
