"""Sample rate of the dxl:// driver over a pseudo-terminal, and live identification errors.

    .venv/bin/python benchmarks/dynamixel_rate.py [--seconds 3] [--samples 4000]

The emulator runs in a child process (an emulator thread would share the
interpreter lock with the loop being timed). The loop is a fixed-period
sampler: slot k is due at ``t0 + k T``; it sleeps to 0.3 ms before the slot and
spins the rest; a sample that starts more than 10 % of T after its slot is
*late*; when the loop has fallen a whole period behind it skips slots
(*missed*) instead of bursting. Each sample is one ``exchange``: a
GroupSyncWrite of the goal and one READ of addresses 120..135.

Table 1: per target rate, the achieved rate, late and missed shares, timeouts,
the exchange time (median, 99th percentile, max) and the CPU the sampling
process used, with the SDK's busy-polling and with the driver's select() wait.
Table 2: parameters identified from a live run at 1 kHz (from the command as
sent, rounded to whole counts, and from the command as requested) against the
same plant simulated directly, without and with the encoder's quantisation.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from servoid.drivers import driver_from_url
from servoid.drivers.bench import BENCH_AMPLITUDE, BENCH_PLANT
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel.emulator import EmulatorProcess, sleep_until
from servoid.errors import DriverError, DriverTimeout
from servoid.ident import MRGIAConfig, identify, simulate

#: Target rates; 0 runs back to back (the ceiling).
RATES_HZ = (100, 500, 1000, 0)
LATE_FRACTION = 0.1
IDENT_LATENCY_MS = 20
SETUP_LATENCY_MS = 20
LOOP_LATENCY_MS = 1.0
CONFIG = MRGIAConfig(na=2, nb=0, delay=1, rho_exponent=0.75)


def sample_loop(servo, u: np.ndarray, rate_hz: float, *, reread: bool = False) -> dict:
    """Run ``u`` through the servo at a fixed rate; return per-sample timing and readings.

    With ``reread``, a sample whose answer was lost is read again: the emulated
    plant steps once per goal written, so the second READ gives that sample's output.
    """
    period = 1.0 / rate_hz if rate_hz else 0.0
    n = len(u)
    y = np.full(n, np.nan)
    latency, late, missed, timeouts, errors = [], 0, 0, 0, 0
    cpu0, start = time.process_time(), time.perf_counter()
    slot = 0
    for k in range(n):
        due = start + slot * period
        now = time.perf_counter()
        if period and now > due + period:  # a whole period behind: skip slots rather than burst
            skipped = int((now - due) / period)
            missed += skipped
            slot += skipped
            due = start + slot * period
        sleep_until(due)
        t0 = time.perf_counter()
        if period and t0 - due > LATE_FRACTION * period:
            late += 1
        try:
            y[k] = servo.exchange(u[k]).position
        except DriverTimeout:
            timeouts += 1
            y[k] = servo.read().position if reread else np.nan
        except DriverError:  # e.g. the late answer to a timed-out READ taken for the next one
            errors += 1
            y[k] = servo.read().position if reread else np.nan
        latency.append(time.perf_counter() - t0)
        slot += 1
    elapsed = time.perf_counter() - start
    return {
        "y": y,
        "rate": n / elapsed,
        "late": late / n,
        "missed": missed,
        "timeouts": timeouts,
        "errors": errors,
        "latency_us": np.array(latency) * 1e6,
        "cpu": (time.process_time() - cpu0) / elapsed,
    }


def timing_table(emu: EmulatorProcess, seconds: float) -> list[tuple]:
    rows = []
    rng = np.random.default_rng(0)
    for poll in ("spin", "select"):
        with driver_from_url(emu.url(1, latency_ms=SETUP_LATENCY_MS)) as servo:
            servo.enable()
            # measured: the reply timeout of a USB adapter set to 1 ms (2 x 1 + 2 ms + wire time),
            # and the SDK's own busy-polling or the driver's select() wait
            servo._port.latency_ms = LOOP_LATENCY_MS
            servo._port.poll = poll
            for rate in RATES_HZ:
                u = rng.uniform(-BENCH_AMPLITUDE, BENCH_AMPLITUDE, int((rate or 2000) * seconds))
                r = sample_loop(servo, u, rate)
                lat = r["latency_us"]
                rows.append((
                    poll, rate or "max", len(u), f"{r['rate']:.1f}", f"{100 * r['late']:.2f}" if rate else "-", r["missed"],
                    f"{r['timeouts']}/{r['errors']}",
                    f"{statistics.median(lat):.0f}", f"{np.percentile(lat, 99):.0f}", f"{lat.max():.0f}",
                    f"{100 * r['cpu']:.0f}",
                ))  # fmt: skip
    return rows


def identification_table(emu: EmulatorProcess, samples: int) -> tuple[list[tuple], dict]:
    u = np.random.default_rng(1).uniform(-BENCH_AMPLITUDE, BENCH_AMPLITUDE, samples)
    # identification does not depend on timing (the emulated plant steps once per goal), so this
    # run uses generous timeouts and reads a lost answer again: a loaded machine must not cut
    # the record into pieces
    with driver_from_url(emu.url(1, latency_ms=IDENT_LATENCY_MS)) as servo:
        servo.enable()
        run = sample_loop(servo, u, 1000, reread=True)
    print(f"identification run: {run['timeouts']} timeouts and {run['errors']} errors, each read again\n")
    # the goal the servo got: u rounded to whole counts (what exchange() reports as the command)
    goal = np.round(u / ct.RAD_PER_COUNT) * ct.RAD_PER_COUNT
    y_direct = simulate(BENCH_PLANT, u).y
    y_quantised = np.round(simulate(BENCH_PLANT, goal).y / ct.RAD_PER_COUNT) * ct.RAD_PER_COUNT
    results = {
        "dxl over pty, 1 kHz": identify(goal, run["y"], CONFIG),
        "same, u as requested": identify(u, run["y"], CONFIG),
        "simulated": identify(u, y_direct, CONFIG),
        "simulated + 12-bit encoder": identify(goal, y_quantised, CONFIG),
    }
    truth = BENCH_PLANT
    names = ("a1", "a2", "b0", "m2", "c1", "c2")
    true = [*truth.a, *truth.b, truth.m2, truth.c1, truth.c2]
    rows = []
    for i, name in enumerate(names):
        row = [name, f"{true[i]:g}"]
        for res in results.values():
            m = res.model
            value = [*m.a, *m.b, m.m2, m.c1, m.c2][i]
            row.append(f"{value:.5f} ({abs(value - true[i]) / abs(true[i]):.1e})")
        rows.append(tuple(row))
    fits = {label: res.fit_nrmse for label, res in results.items()}
    return rows, fits


def print_table(title: str, header: tuple, rows: list[tuple]) -> None:
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    print(title)
    print("  ".join(str(h).rjust(w) for h, w in zip(header, widths)))
    for row in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(row, widths)))
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0, help="seconds per rate (default 3)")
    parser.add_argument("--samples", type=int, default=4000, help="samples of the identification run (default 4000)")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    print(f"machine: {os.cpu_count()} CPUs, load average {load_before:.2f} at the start\n")
    with EmulatorProcess([1]) as emu:
        timing = timing_table(emu, args.seconds)
        print_table(
            "Dynamixel (dxl:// over a pty, emulator in another process): one exchange = SyncWrite goal + READ 120..135",
            ("wait", "target Hz", "samples", "achieved Hz", "late %", "missed", "timeouts/errors",
             "median us", "p99 us", "max us", "CPU %"),
            timing,
        )  # fmt: skip
    with EmulatorProcess([1]) as emu:  # a servo at rest, like the simulation it is compared with
        ident_rows, fits = identification_table(emu, args.samples)
    print_table(
        f"Identification from {args.samples} samples, value (relative error); MRGIA rho exponent 0.75 + refinement",
        ("param", "true", *fits),
        ident_rows,
    )
    print("free-run NRMSE: " + ", ".join(f"{k} {v:.4f}" for k, v in fits.items()))
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
