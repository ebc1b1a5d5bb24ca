"""Every way out turns the torque off: a host stopped with SIGTERM, or killed with SIGKILL, leaves every emulated servo off.

Each emulator runs as ``servoid emulate KIND`` in a process of its own, with
its default servo behind it (a physical twin: xm430 behind the firmware and
the Dynamixel, the cia402 and odrive twins behind the CAN drives), the host
as ``servoid identify --driver URL`` in another. The test waits until the
host is sampling (its recording grows), then

* SIGTERM: the command stops as on Ctrl-C (exit 130, one line, no traceback)
  and switches the torque off on its way out -- the emulator reports the
  power stage going off, before the host has exited;
* SIGKILL: nothing of the host runs again; the servo's own watchdog, which
  the driver configured (the serial firmware's, the Dynamixel Bus Watchdog,
  the CiA 402 heartbeat consumer) or the board has (the ODrive axis
  watchdog), switches it off -- the emulator reports when, on the monotonic
  clock this test reads too, within the watchdog's time of the kill.
  The Feetech STS has no watchdog (docs/feetech.md): after a SIGKILL it
  holds its last goal with the torque on, which the test checks too, so
  that the documentation's warning stays true.

Run with ``-s`` to see the times measured.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from .can_helpers import free_udp_port

#: The watchdog every driver (or, for the ODrive, the emulated board) sets by default, s.
WATCHDOG_S = 0.5
#: Slack on a loaded 2-core machine: the emulator notices silence in its own loop (5 to 50 ms), and
#: the host's last packet came at most a period before the kill.
SLACK_S = 0.3
RATE_HZ = 50.0
_MONOTONIC = re.compile(r"monotonic ([0-9.]+) s")


@dataclass
class Process:
    """A child process whose output lines are collected as they come, with the time each came."""

    proc: subprocess.Popen[str]
    lines: list[str] = field(default_factory=list)

    def start_readers(self) -> None:
        for stream in (self.proc.stdout, self.proc.stderr):
            threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream) -> None:  # noqa: ANN001 - a text stream
        for line in stream:
            self.lines.append(line.rstrip("\n"))

    def wait_for(self, pattern: str, timeout: float = 60.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.lines):
                found = re.search(pattern, line)
                if found:
                    return found
            if self.proc.poll() is not None and not any(re.search(pattern, x) for x in self.lines):
                time.sleep(0.1)
                if not any(re.search(pattern, x) for x in self.lines):
                    break
            time.sleep(0.01)
        raise AssertionError(f"no line matching {pattern!r} in: {self.lines}")


def _spawn(*args: str) -> Process:
    env = dict(os.environ, COLUMNS="400")  # rich would wrap the emulators' event lines at 80 columns
    proc = subprocess.Popen([sys.executable, "-m", "servoid", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, start_new_session=True)  # fmt: skip
    child = Process(proc)
    child.start_readers()
    return child


@contextmanager
def emulator(kind: str) -> Iterator[tuple[Process, str]]:
    port = free_udp_port()
    args = {
        "serial": ["emulate", "serial"],
        "dxl": ["emulate", "dxl", "--rate", f"{RATE_HZ:g}"],
        "feetech": ["emulate", "feetech", "--rate", f"{RATE_HZ:g}"],
        "cia402": ["emulate", "can", "--port", str(port), "--quiet"],
        "odrive": [
            "emulate",
            "can",
            "--protocol",
            "odrive",
            "--node",
            "3",
            "--port",
            str(port),
            "--rate",
            f"{RATE_HZ:g}",
            "--watchdog",
            f"{WATCHDOG_S:g}",
            "--quiet",
        ],  # fmt: skip
    }[kind]
    emu = _spawn(*args)
    try:
        url = emu.wait_for(r"((?:serial|dxl|feetech|can)://\S+?)'?$").group(1)
        yield emu, url
    finally:
        emu.proc.send_signal(signal.SIGTERM)
        try:
            emu.proc.wait(10)
        except subprocess.TimeoutExpired:
            emu.proc.kill()
            emu.proc.wait()


def _host(url: str, out: Path) -> Process:
    host = _spawn("identify", "--driver", url, "--rate", f"{RATE_HZ:g}", "--samples", "100000", "--no-plots", "--no-probe", "--allow-lost",
                  "--out", str(out))  # fmt: skip
    recording = out / "recording.csv"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if recording.exists() and recording.read_text(errors="replace").count("\n") > 40:  # sampling, torque on
            return host
        assert host.proc.poll() is None, f"the host ended early: {host.lines}"
        time.sleep(0.05)
    raise AssertionError(f"the host never started sampling: {host.lines}")


def _event_time(emu: Process, pattern: str, after: int) -> tuple[str, float]:
    deadline = time.monotonic() + WATCHDOG_S + 5.0
    while time.monotonic() < deadline:
        for line in emu.lines[after:]:
            if re.search(pattern, line):
                stamp = _MONOTONIC.search(line)
                assert stamp, line
                return line, float(stamp.group(1))
        time.sleep(0.005)
    raise AssertionError(f"no {pattern!r} from the emulator after the kill: {emu.lines[after:]}")


#: What each emulator says when the host's torque-off arrives, and when its watchdog acts.
OFF = {"serial": r"servoid-bench-fw: torque off", "dxl": r"servo 1: torque off", "feetech": r"servo 1: torque off",
       "cia402": r"node 1: power stage off", "odrive": r"node 3: power stage off"}  # fmt: skip
#: The servos with no watchdog of their own: a killed host leaves them holding, torque on.
NO_WATCHDOG = {"feetech"}
WATCHDOG = {
    "serial": r"watchdog: no request within the watchdog time, torque off",
    "dxl": r"servo 1: bus watchdog expired",
    "cia402": r"node 1: heartbeat of node 127 lost",
    "odrive": r"node 3: axis watchdog expired",
}


def _exercise(kind: str, tmp: Path) -> str:
    """SIGTERM one host, then SIGKILL another, on one emulator; a line with the times measured."""
    with emulator(kind) as (emu, url):
        # SIGTERM: the command stops as on Ctrl-C and switches the torque off on its way out
        host = _host(url, tmp / "term")
        seen = len(emu.lines)
        killed = time.monotonic()
        host.proc.send_signal(signal.SIGTERM)
        assert host.proc.wait(30) == 130, host.lines
        exited = time.monotonic() - killed
        time.sleep(0.1)
        assert "servoid identify: interrupted" in host.lines, host.lines  # one line, as after Ctrl-C
        assert not any("Traceback" in line for line in host.lines)
        _, at = _event_time(emu, OFF[kind], seen)
        off = at - killed
        assert off < exited and exited < 10.0  # the torque was off before the host had exited
        # SIGKILL: only the servo's own watchdog is left to switch it off
        host = _host(url, tmp / "kill")
        seen = len(emu.lines)
        killed = time.monotonic()
        os.kill(host.proc.pid, signal.SIGKILL)
        if kind in NO_WATCHDOG:
            host.proc.wait(10)
            time.sleep(WATCHDOG_S + SLACK_S)
            assert not any(re.search(OFF[kind], line) for line in emu.lines[seen:]), emu.lines[seen:]
            return f"{kind}: SIGTERM off after {off * 1e3:.0f} ms; SIGKILL: no watchdog, still holding (as documented)"
        line, at = _event_time(emu, WATCHDOG[kind], seen)
        host.proc.wait(10)
        # the watchdog counts from the last packet (CiA 402: heartbeat), which came up to 125 ms before the kill
        assert WATCHDOG_S - 0.25 < at - killed < WATCHDOG_S + SLACK_S, line
        return (f"{kind}: SIGTERM off after {off * 1e3:.0f} ms; SIGKILL off after {(at - killed) * 1e3:.0f} ms "
                f"(watchdog {WATCHDOG_S * 1e3:.0f} ms): {line}")  # fmt: skip


@pytest.mark.timeout(240)
def test_sigterm_and_sigkill_of_the_host_leave_every_emulated_servo_off(tmp_path):
    kinds = ["serial", "dxl", "feetech", "cia402", "odrive"]
    # the four emulators side by side: each measures its own servo, and the run takes as long as the slowest
    with ThreadPoolExecutor(len(kinds)) as pool:
        futures = {kind: pool.submit(_exercise, kind, tmp_path / kind) for kind in kinds}
        lines = [futures[kind].result() for kind in kinds]
    print("\n" + "\n".join(lines))
