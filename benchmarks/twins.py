"""The physical servo twins: what 1 ms of servo time costs, and what identification makes of them.

Run: ``.venv/bin/python benchmarks/twins.py [--repeat 5] [--samples 6000]``.

Two tables, one row per preset:

1. **Speed.** The firmware's rates and the sub-step, then the cost of
   ``Twin.advance(0.001)`` (one emulator period at 1 kHz, through the Python
   object: what an emulator pays), the compiled kernel alone for the same
   millisecond, and a floor measured in the same run: a bare call of a
   compiled no-op with the same arguments (numba's dispatch cost). Best of
   ``--repeat`` rounds of 2000 calls; the budget is 50 us per ms.
2. **Identification (offline).** Each twin, torque on, driven by a bounded
   white set point (uniform, +-0.1 rad, seeded) at 100 Hz, sampled as a host
   does (:meth:`Twin.sample`: read at the command's arrival, command latched
   at the drive's next tick); ``servoid.ident.identify`` with default
   settings (``MRGIAConfig()``: na 2, nb 0, delay 1, no structure flags) on
   (command, output encoder). Printed as they are: the true play, the
   identified ``c1 + c2``, its error, the fit's free-run NRMSE, and what the
   drive did meanwhile (shares of its ticks with saturated duty and with the
   current command at its limit, share of the time the motor was stuck,
   whether the online estimate settled or the drive faulted). Nothing here
   is tuned to make these numbers good.

The machine may be shared: the speed table is the best of the repeats.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers.twin import Twin, preset, preset_names
from servoid.drivers.twin._jit import jit
from servoid.drivers.twin.kernel import run
from servoid.errors import ServoidError
from servoid.ident import MRGIAConfig, identify

HOST_RATE_HZ = 100.0
AMPLITUDE_RAD = 0.1
CALLS = 2000


@jit
def _noop(
    phys: np.ndarray,
    fw: np.ndarray,
    state: np.ndarray,
    mem: np.ndarray,
    n_sub: int,
    noise_m: np.ndarray,
    noise_l: np.ndarray,
    noise_at: int,
) -> int:
    """The floor: a compiled function with the kernel's arguments that does nothing."""
    return noise_at


def best_per_call(fn, repeat: int) -> float:
    """Best mean time of one call over ``repeat`` rounds of CALLS calls, us."""
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(CALLS):
            fn()
        best = min(best, (time.perf_counter() - start) / CALLS)
    return best * 1e6


def speed_row(name: str, repeat: int) -> list[str]:
    twin = Twin(preset(name), seed=1)
    twin.enable()
    twin.command(0.05)
    twin.advance(0.01)  # compile and settle
    per_ms = best_per_call(lambda: twin.advance(1e-3), repeat)
    phys, fw = twin.params.pack()
    state = twin._state.copy()  # the kernel alone, on a copy of the running state
    mem = twin._mem.copy()
    empty = np.zeros(0)
    n_sub = int(round(1e-3 / twin.params.substep_s))
    kernel = best_per_call(lambda: run(phys, fw, state, mem, n_sub, empty, empty, 0), repeat)
    _noop(phys, fw, state, mem, 0, empty, empty, 0)
    floor = best_per_call(lambda: _noop(phys, fw, state, mem, 0, empty, empty, 0), repeat)
    p = twin.params
    return [
        name,
        f"{p.control_rate_hz:g}",
        f"{p.current_rate_hz:g}",
        f"{p.substep_s * 1e6:.3g}",
        f"{n_sub}",
        f"{per_ms:.1f}",
        f"{kernel:.1f}",
        f"{floor:.2f}",
        f"{per_ms / floor:.0f}x",
        "yes" if per_ms <= 50.0 else "NO",
    ]


def ident_row(name: str, samples: int, seed: int) -> list[str]:
    twin = Twin(preset(name), seed=seed)
    twin.enable()
    u = np.random.default_rng(seed).uniform(-AMPLITUDE_RAD, AMPLITUDE_RAD, samples)
    rec = twin.sample(u, 1.0 / HOST_RATE_HZ)
    play = twin.truth.play_rad
    counters = twin.counters
    fault = twin.read().fault
    limited = counters.current_limited_ticks / counters.ticks if counters.ticks else 0.0
    try:
        result = identify(rec.u, rec.y, MRGIAConfig())
    except ServoidError as exc:
        return [
            name,
            f"{play:.5f}",
            "failed",
            "-",
            "-",
            "-",
            "-",
            f"{counters.saturated_share:.2f}",
            f"{limited:.2f}",
            f"{counters.stuck_motor_s / counters.time_s:.2f}",
            str(exc)[:40],
        ]
    m = result.model
    width = m.c1 + m.c2
    return [
        name,
        f"{play:.5f}",
        f"{width:.5f}",
        f"{width - play:+.5f}",
        f"{(width - play) / play:+.1f}",
        f"{m.m2:.3f}",
        f"{result.fit_nrmse:.4f}",
        f"{counters.saturated_share:.2f}",
        f"{limited:.2f}",
        f"{counters.stuck_motor_s / counters.time_s:.2f}",
        fault or ("settled" if result.mrgia.settled else "not settled"),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timing rounds (best is kept)")
    parser.add_argument("--samples", type=int, default=6000, help="host samples per identification")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load (1 min): {load:.2f} on {os.cpu_count()} cores; times are the best of {args.repeat} rounds")

    rows = [speed_row(name, args.repeat) for name in preset_names()]
    table(
        "Cost of servo time (Twin.advance(0.001), i.e. an emulator at 1 kHz)",
        [
            "preset",
            "control Hz",
            "current Hz",
            "sub-step us",
            "sub-steps/ms",
            "us per ms",
            "kernel us",
            "floor us",
            "x floor",
            "<= 50 us",
        ],
        rows,
    )

    rows = [ident_row(name, args.samples, args.seed) for name in preset_names()]
    table(
        f"Offline identification: white set point +-{AMPLITUDE_RAD} rad at {HOST_RATE_HZ:g} Hz, "
        f"{args.samples} samples, identify(u, y, MRGIAConfig())",
        [
            "preset",
            "true play rad",
            "c1+c2 rad",
            "error rad",
            "rel. error",
            "m2",
            "fit NRMSE",
            "duty sat.",
            "current lim.",
            "motor stuck",
            "online",
        ],
        rows,
    )


if __name__ == "__main__":
    main()
