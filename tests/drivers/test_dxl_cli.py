"""``servoid emulate dxl``: prints where it is, serves a driver from another process, stops on Ctrl-C."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys

import pytest

from servoid.drivers import driver_from_url

from . import ctrl_c_reaches_it
from .dxl_helpers import TEST_LATENCY_MS


@pytest.mark.slow
@pytest.mark.timeout(60)
def test_emulate_dxl_prints_the_port_and_serves_until_interrupted(tmp_path):
    link = tmp_path / "ttyDXL"
    proc = subprocess.Popen(
        [sys.executable, "-m", "servoid", "emulate", "dxl", "--ids", "1,4", "--link", str(link)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_reaches_it,
    )  # fmt: skip
    try:
        lines = []
        while not lines or not lines[-1].startswith("serving"):
            line = proc.stdout.readline()
            assert line, f"the emulator ended early: {proc.stderr.read()}"
            lines.append(line.strip())
        assert re.fullmatch(r"Dynamixel emulator on /dev/pts/\d+ \(Protocol 2\.0, XM430-W350, any baud rate, "
                            r"sampled at 200 Hz\)", lines[0])  # fmt: skip
        # the servos' clock at real-time priority where the system permits it, as a live session's emulators; said
        said = [line for line in lines if line.startswith("real-time priority: ")]
        fifo = os.sched_getscheduler(proc.pid) & ~os.SCHED_RESET_ON_FORK == os.SCHED_FIFO
        assert len(said) == 1 and ("SCHED_FIFO" in said[0]) == fifo and ("not permitted" in said[0]) != fifo
        urls = [line.split(": ", 1)[1] for line in lines if line.startswith("servo ")]
        assert urls == [f"dxl://{link}?id=1&baud=1000000", f"dxl://{link}?id=4&baud=1000000"]
        with driver_from_url(f"{urls[1]}&latency_ms={TEST_LATENCY_MS}") as servo:
            servo.enable()
            positions = [servo.exchange(0.3).position for _ in range(30)]  # 0.15 s of the XM430 twin
            assert servo.identity["id"] == 4 and positions[-1] > 0.25
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert re.search(r"stopped: \d+ packets received", out) and not link.exists()
