"""CAN drivers: sample rate, late share and latency per protocol and transport, and identification.

Run:  .venv/bin/python benchmarks/can_rate.py [--seconds 2] [--rates 100 500 1000]

For each protocol (CiA 402 through canopen, ODrive CAN Simple) and transport
(python-can ``virtual`` with the simulated drive in this process,
``udp_multicast`` with the drive in another process started by
``servoid emulate can``), a fixed-period loop drives the servo at 100 Hz,
500 Hz and 1 kHz for ``--seconds`` each, with the seeded uniform bench input
(amplitude BENCH_AMPLITUDE). The loop is what a sampling session does:
sleep to 0.3 ms before the slot, spin to it, exchange; when it has fallen a
whole period behind it skips slots instead of bursting.

Per run: achieved rate (exchanges per second of wall time), late share
((late + skipped) / slots; late = started more than 10 % of a period after
its slot, or answered after the next slot began), and the exchange latency
(median, 99th percentile, maximum). Then the backlash model is identified
(MRGIA with rho exponent 0.75, then refinement) from the samples of the
fastest run and compared with the same identification on the plant simulated
directly with the same inputs: the drives are sample-synchronous, so the
transport changes the timing, not the data.

Identification uses the fastest run, which comes first and so starts, like
the direct simulation, with the plant at rest.

The machine's load is printed before and after: on a shared 2-core machine
the tails (99th percentile, late share at 1 kHz) are the scheduler's.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from rich.console import Console

from servoid.cli import _term
from servoid.drivers import Driver, driver_from_url
from servoid.drivers.bench import BENCH_AMPLITUDE, BENCH_PLANT
from servoid.drivers.can._bus import BusAddress
from servoid.drivers.can.simulated import simulated_drive
from servoid.errors import DriverTimeout
from servoid.ident import MRGIAConfig, identify, simulate

SPIN_NS = 300_000  # sleep until this long before a slot, then spin (time.sleep overshoots ~50 us)
PROTOCOLS = ("cia402", "odrive")
TRANSPORTS = ("virtual", "udp_multicast")


@dataclass(frozen=True)
class Run:
    """One paced run."""

    target_hz: float
    slots: int
    exchanges: int
    late: int
    skipped: int
    timeouts: int
    elapsed_s: float
    latency_us: np.ndarray
    u: np.ndarray
    y: np.ndarray

    @property
    def rate_hz(self) -> float:
        return self.exchanges / self.elapsed_s

    @property
    def late_share(self) -> float:
        return (self.late + self.skipped + self.timeouts) / self.slots


def paced_run(servo: Driver, u: np.ndarray, rate_hz: float) -> Run:
    """Exchange ``u`` at a fixed rate (one slot per sample; skipped slots use no input)."""
    period = round(1e9 / rate_hz)
    slots = u.size
    latency, sent, measured = [], [], []
    late = skipped = timeouts = 0
    start = time.perf_counter_ns() + period
    slot = 0
    while slot < slots:
        deadline = start + slot * period
        now = time.perf_counter_ns()
        if now >= deadline + period:  # a whole period behind: skip, do not burst
            behind = (now - deadline) // period
            skipped += int(min(behind, slots - slot))
            slot += int(behind)
            continue
        if deadline - now > SPIN_NS:
            time.sleep((deadline - now - SPIN_NS) / 1e9)
        while time.perf_counter_ns() < deadline:
            pass
        began = time.perf_counter_ns()
        try:
            m = servo.exchange(float(u[slot]))
        except DriverTimeout:
            timeouts += 1
            slot += 1
            continue
        ended = time.perf_counter_ns()
        latency.append((ended - began) / 1e3)
        sent.append(m.command)
        measured.append(m.position)
        if began - deadline > period // 10 or ended > deadline + period:
            late += 1
        slot += 1
    elapsed = (time.perf_counter_ns() - start) / 1e9
    return Run(
        target_hz=rate_hz, slots=slots, exchanges=len(sent), late=late, skipped=skipped, timeouts=timeouts,
        elapsed_s=elapsed, latency_us=np.array(latency), u=np.array(sent), y=np.array(measured),
    )  # fmt: skip


@contextmanager
def drive_url(protocol: str, transport: str) -> Iterator[str]:
    """A simulated drive on ``transport``; yields the URL that reaches it."""
    if transport == "virtual":
        with simulated_drive(protocol, bus=BusAddress("virtual", f"bench-{uuid.uuid4().hex[:8]}")) as drive:
            yield drive.url()
        return
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        port = s.getsockname()[1]
    cmd = [sys.executable, "-m", "servoid", "emulate", "can", "--protocol", protocol, "--port", str(port), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip() if proc.stdout else ""
        if not url.startswith("can://"):
            raise RuntimeError(f"the emulator did not start: {' '.join(cmd)}")
        yield url
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=2.0, help="length of each paced run, s (default 2)")
    parser.add_argument("--rates", type=float, nargs="+", default=[100.0, 500.0, 1000.0], help="target rates, Hz")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    load_before = os.getloadavg()
    rng = np.random.default_rng(args.seed)
    timing_rows, ident_rows = [], []
    config = MRGIAConfig(rho_exponent=0.75)
    for protocol in PROTOCOLS:
        for transport in TRANSPORTS:
            with drive_url(protocol, transport) as url, driver_from_url(url) as servo:
                servo.enable()
                runs = []
                # fastest first: it starts with the plant at rest, as simulate() does, and is identified
                for rate in sorted(args.rates, reverse=True):
                    u = rng.uniform(-BENCH_AMPLITUDE, BENCH_AMPLITUDE, int(rate * args.seconds))
                    runs.append(paced_run(servo, u, rate))
            for run in sorted(runs, key=lambda r: r.target_hz):
                lat = run.latency_us
                timing_rows.append((
                    f"{protocol} / {transport}", f"{run.target_hz:.0f}", f"{run.rate_hz:.1f}",
                    f"{100 * run.late_share:.2f} %", run.skipped, run.timeouts,
                    f"{np.median(lat):.0f}", f"{np.percentile(lat, 99):.0f}", f"{lat.max():.0f}",
                ))  # fmt: skip
            fastest = runs[0]
            live = identify(fastest.u, fastest.y, config)
            direct = identify(fastest.u, simulate(BENCH_PLANT, fastest.u).y, config)
            ident_rows.append((
                f"{protocol} / {transport}", f"{fastest.target_hz:.0f}", fastest.exchanges,
                f"{live.mrgia_model.max_relative_error(BENCH_PLANT):.2e}" if live.mrgia_model else "invalid",
                f"{live.model.max_relative_error(BENCH_PLANT):.2e}",
                f"{direct.model.max_relative_error(BENCH_PLANT):.2e}",
                f"{live.fit_nrmse:.2e}",
            ))  # fmt: skip
    load_after = os.getloadavg()

    console = Console(width=132, highlight=False)
    _term.table(
        f"CAN exchange timing ({args.seconds:g} s per run; latency in us)",
        ["protocol / transport", "target Hz", "achieved Hz", "late", "skipped", "timeouts", "p50", "p99", "max"],
        timing_rows,
        console=console,
    )
    _term.table(
        "Identification of BENCH_PLANT from the fastest run (max relative parameter error)",
        ["protocol / transport", "at Hz", "samples", "MRGIA", "refined", "plant itself", "fit NRMSE"],
        ident_rows,
        console=console,
    )
    cores = os.cpu_count()
    print(
        f"load average (1/5/15 min) before {load_before[0]:.2f}/{load_before[1]:.2f}/{load_before[2]:.2f}, "
        f"after {load_after[0]:.2f}/{load_after[1]:.2f}/{load_after[2]:.2f} on {cores} cores"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
