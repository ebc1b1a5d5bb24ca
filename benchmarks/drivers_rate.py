"""Sample rate, late share and identification accuracy of the live path, over the pty and in simulation.

Run: ``.venv/bin/python benchmarks/drivers_rate.py`` (about a minute). Prints
three tables:

1. per-exchange latency: back-to-back set-point exchanges (no schedule) over
   the serial pseudo-terminal (pyserial driver <-> compiled firmware in its own
   process) and with the simulated servo in this process;
2. the sampling session over the serial pty at 100 Hz, 500 Hz and 1 kHz: the
   rate answered, and the share of ok / late / missed / timed-out slots;
3. identification of MODEL_PLANT from the same excitation on the serial path
   and on the simulated driver (virtual time: no timing faults at all), as the
   maximum relative parameter error of the online MRGIA and of the refined model.

The machine's load is printed first: the numbers are only as good as the
scheduler's attention (a 2-core machine shared with other jobs shows it).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers import driver_from_url
from servoid.drivers.model_plant import MODEL_AMPLITUDE, MODEL_PLANT
from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions
from servoid.ident import MRGIA, MRGIAConfig, identify
from servoid.session import SessionConfig, run_session


def latency(url: str, n: int) -> np.ndarray:
    u = np.random.default_rng(0).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, n)
    out = np.empty(n)
    with driver_from_url(url) as servo:
        servo.enable()
        for i, v in enumerate(u):
            start = time.perf_counter_ns()
            servo.exchange(v)
            out[i] = (time.perf_counter_ns() - start) / 1e3
    return out


def session(url: str, rate: float, u: np.ndarray):
    est = MRGIA(MRGIAConfig())
    with driver_from_url(url) as servo:
        result = run_session(servo, u, SessionConfig(period_s=1.0 / rate), estimator=est)
        stats = servo.stats
    return result, est, stats


def pct(x: float) -> str:
    return f"{100 * x:.2f} %"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=6.0, help="length of each rate run (default 6 s)")
    parser.add_argument("--samples", type=int, default=5000, help="samples of the accuracy runs (default 5000)")
    args = parser.parse_args()

    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} CPUs, load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1/5/15 min)")

    with FirmwareEmulator(FirmwareOptions(servo="model")) as emu:
        rows = []
        for name, url in (("serial pty (pyserial <-> C firmware)", emu.url), ("sim (same process)", "sim://model")):
            lat = latency(url, 3000)
            rows.append([name, f"{np.median(lat):.0f}", f"{np.percentile(lat, 90):.0f}",
                         f"{np.percentile(lat, 99):.0f}", f"{1e6 / np.median(lat):.0f}"])  # fmt: skip
        table("1. one set-point exchange, back to back (us)", ["path", "median", "p90", "p99", "max rate Hz"], rows)

    rows = []
    rng = np.random.default_rng(1)
    for rate in (100.0, 500.0, 1000.0):
        n = int(args.seconds * rate)
        with FirmwareEmulator(FirmwareOptions(servo="model")) as fresh:
            result, _, stats = session(fresh.url, rate, rng.uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, n))
        c, total = result.counts, len(result)
        sent = np.isfinite(result.t_actual)
        lateness = (result.t_actual - result.t)[sent] * 1e6
        rows.append([f"{rate:g}", f"{result.achieved_rate_hz:.1f}", pct(c["ok"] / total), pct(c["late"] / total),
                     pct(c["missed"] / total), pct(c["timeout"] / total), f"{np.percentile(lateness, 99):.0f}",
                     f"{np.nanmedian(result.exchange_s) * 1e6:.0f}", str(stats.rejected)])  # fmt: skip
    table(f"2. sampling session over the serial pty ({args.seconds:g} s each)",
          ["asked Hz", "answered Hz", "ok", "late", "missed", "timeout", "start p99 us", "exchange us",
           "rejected"], rows)  # fmt: skip

    u = np.random.default_rng(2).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, args.samples)
    rows = []
    for name, url, rate in (
        ("sim, virtual time", "sim://model?clock=virtual", 500.0),
        ("sim, real time", "sim://model", 500.0),
        ("serial pty", "serial", 500.0),
        ("serial pty", "serial", 1000.0),
    ):
        with FirmwareEmulator(FirmwareOptions(servo="model")) as fresh:  # every run starts from a servo at rest
            result, est, _ = session(fresh.url if url == "serial" else url, rate, u)
        ident = identify(result.u, result.y, MRGIAConfig(), valid=result.valid)
        online = est.model.max_relative_error(MODEL_PLANT)
        rows.append([name, f"{rate:g}", f"{int(result.valid.sum())}/{len(result)}", f"{online:.2e}",
                     f"{ident.model.max_relative_error(MODEL_PLANT):.2e}", f"{ident.fit_nrmse:.2e}"])  # fmt: skip
    table(f"3. identifying MODEL_PLANT, {args.samples} samples of uniform +/-{MODEL_AMPLITUDE} rad",
          ["path", "Hz", "used samples", "MRGIA max rel err", "refined max rel err", "fit NRMSE"], rows)  # fmt: skip
    load = os.getloadavg()
    print(f"\nload average at the end: {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}")


if __name__ == "__main__":
    main()
