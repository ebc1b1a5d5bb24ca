"""The dxl:// driver's reply wait: the SDK's busy-polling against the driver's select(), through the session.

    .venv/bin/python benchmarks/dynamixel_rate.py [--seconds 3]

The emulator runs in a child process on a pseudo-terminal (an emulator thread
would share the interpreter lock with the loop being timed), sampled on its
own clock at the session's rate. Each sample is one exchange: a
GroupSyncWrite of the goal and one READ of addresses 120..135. The reply
timeout is that of a USB adapter whose latency timer is set to 1 ms (2 x 1 +
2 ms plus the wire time).

Per wait and target rate, through :func:`servoid.session.run_session`: the
rate answered, the ok / late / missed / timed-out shares, the exchange time
(median, 99th percentile) and the CPU the sampling process used. The
dynamixel-sdk polls the port in a tight loop until the reply is complete,
burning a core; the driver's port handler waits in select() instead, which
leaves the core to the emulator, the estimator, or another servo's driver.

Rates and identification across all transports: benchmarks/transports_rate.py.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers import driver_from_url
from servoid.drivers.dynamixel.emulator import EmulatorProcess
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.session import SessionConfig, run_session

RATES_HZ = (100.0, 500.0, 1000.0)
LOOP_LATENCY_MS = 1.0


def run(poll: str, rate: float, seconds: float) -> list[str]:
    u = np.random.default_rng(0).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, int(rate * seconds))
    with EmulatorProcess([1], return_delay_us=0, period_s=1 / rate, servo="model") as emu:
        with driver_from_url(emu.url(1, latency_ms=LOOP_LATENCY_MS)) as servo:
            servo._port.poll = poll  # the SDK's own busy-polling, or the driver's select() wait
            cpu0, wall0 = time.process_time(), time.perf_counter()
            result = run_session(servo, u, SessionConfig(period_s=1 / rate))
            cpu = (time.process_time() - cpu0) / (time.perf_counter() - wall0)
    n = len(result)
    share = [f"{100 * result.counts[k] / n:.2f} %" for k in ("ok", "late", "missed", "timeout")]
    exchange = result.exchange_s[np.isfinite(result.exchange_s)] * 1e6
    return [poll, f"{rate:g}", f"{result.achieved_rate_hz:.1f}", *share, f"{np.median(exchange):.0f}",
            f"{np.percentile(exchange, 99):.0f}", f"{100 * cpu:.0f} %"]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0, help="seconds per run (default 3)")
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at the start")
    rows = [run(poll, rate, args.seconds) for poll in ("spin", "select") for rate in RATES_HZ]
    table("dxl:// over a pty, through the sampling session (SyncWrite goal + READ 120..135 per sample)",
          ["wait", "asked Hz", "answered Hz", "ok", "late", "missed", "timeout", "exchange p50 us", "p99 us", "CPU"],
          rows)  # fmt: skip
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
