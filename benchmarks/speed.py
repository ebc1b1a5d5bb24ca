"""The hot paths against their floors, measured in the same run: update, batch replay, the session, identify().

Run: ``.venv/bin/python benchmarks/speed.py`` (about a minute; ``--full``
adds identify() at 10^7 samples, several minutes and some GB).

Every row is the best of ``--repeat`` runs in each of ``--rounds`` rounds,
the rows taking turns, so that a shared machine's busy spells drop out of a
row and its floor alike; the load average is printed with the tables.

``MRGIA.update``
    One online step on the paper's plant at SNR 43, called from Python (us
    per sample). Floor: a compiled function that does nothing, called as the
    update calls its kernel (its one buffer and two floats, through the
    compiled entry point, past numba's dispatch: ``servoid.ident._jit.direct_call``):
    the cheapest call into compiled code with the update's inputs.
batch replay
    :func:`run_mrgia` over 10^6 samples (M samples/s). Floors: a NumPy pass
    over the same arrays (``u @ y``) and a compiled loop reading both.
the session's own work
    :func:`run_session` on the simulated servo (virtual clock) minus the
    bare ``driver.exchange`` loop over the same servo, with the slot numbers
    the session passes, its virtual clock slept to each slot as the session
    sleeps it (without that the simulated servo integrated less time per
    exchange, about 1.4 us of physics a sample charged to the session) (us per sample): the
    sampler alone, with the MRGIA fed, and with the recording written too
    (a CSV row per sample, handed to the operating system as it arrives).
    A diagnostic row repeats the first with a servo that answers at once
    (a constant :class:`Measurement`, the device clock on time): the
    session's own work without the simulated servo's Python beside it. The
    session adds about 4 % to the simulated servo's instructions per
    exchange (callgrind: 9.0k to 211.8k), but 10-15 % to its time: the
    exchange itself runs slower inside the session than in the bare loop
    (same calls, same physics; no hardware counters on the machine to say
    why), and the target's row charges that to the session.
identify()
    At 10^3 ... 10^6 samples (10^7 with ``--full``), each size in a fresh
    process, the MRGIA's history kept as ``servoid identify`` keeps it: CPU
    time, peak memory added (traced in a second run: NumPy's arrays, the
    record already in memory), bytes per sample and the slope of time
    against length (log-log, from the size before).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers import driver_from_url
from servoid.drivers.base import Measurement
from servoid.ident import MRGIA, PAPER_PLANT, MRGIAConfig, noise_epsilon, run_mrgia, simulate
from servoid.ident._jit import direct_call
from servoid.session import SessionConfig, run_session

URL = "sim://?clock=virtual&snr=40&seed=1"
PERIOD_S = 1e-3


def _paper_record(samples: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, MRGIAConfig]:
    rng = np.random.default_rng(seed)
    sim = simulate(PAPER_PLANT, rng.uniform(-2.4, 2.4, samples), snr=43.0, rng=rng)
    return sim.u, sim.y, MRGIAConfig(epsilon=noise_epsilon(sim.noise_std), rho_exponent=0.75)


def _best(run: Callable[[], float], repeat: int) -> float:
    return min(run() for _ in range(repeat))


# ---- update -------------------------------------------------------------------------------
def update_rows(samples: int, repeat: int) -> dict[str, float]:
    from numba import njit

    @njit
    def bare(buf, u, y):  # type: ignore[no-untyped-def]
        return 0

    u, y, config = _paper_record(samples)
    ul, yl = u.tolist(), y.tolist()
    est = MRGIA(config)
    est.update(ul[0], yl[0])  # compiled before the clock starts
    call = partial(direct_call(bare, est._buf, 0.0, 0.0), est._buf)  # as MRGIA binds its kernel

    def floor() -> float:
        t0 = time.process_time_ns()
        for a, b in zip(ul, yl):
            call(a, b)
        return (time.process_time_ns() - t0) / samples / 1e3

    def update() -> float:
        e = MRGIA(config)
        step = e.update
        t0 = time.process_time_ns()
        for a, b in zip(ul, yl):
            step(a, b)
        return (time.process_time_ns() - t0) / samples / 1e3

    return {"update": _best(update, repeat), "update floor": _best(floor, repeat)}


# ---- batch replay ---------------------------------------------------------------------------
def batch_rows(samples: int, repeat: int) -> dict[str, float]:
    from numba import njit

    @njit
    def read_both(u, y):  # type: ignore[no-untyped-def]
        acc = 0.0
        for k in range(u.shape[0]):
            acc += u[k] * y[k]
        return acc

    u, y, config = _paper_record(samples)
    run_mrgia(u[:2000], y[:2000], config)
    read_both(u, y)

    def timed(f: Callable[[], object]) -> Callable[[], float]:
        def run() -> float:
            t0 = time.process_time()
            f()
            return samples / (time.process_time() - t0) / 1e6

        return run

    every = max(1, samples // 2000)  # the history `servoid identify` keeps
    return {
        "batch": max(timed(lambda: run_mrgia(u, y, config, record_every=every))() for _ in range(repeat)),
        "batch numpy": max(timed(lambda: u @ y)() for _ in range(repeat)),
        "batch loop": max(timed(lambda: read_both(u, y))() for _ in range(repeat)),
    }


# ---- session ----------------------------------------------------------------------------------
def session_rows(samples: int, repeat: int) -> dict[str, float]:
    u = np.random.default_rng(2).uniform(-0.2, 0.2, samples)

    def exchange() -> float:
        with driver_from_url(URL) as servo:
            servo.set_sample_period(PERIOD_S)
            servo.enable()
            exchange, sleep_until = servo.exchange, servo.clock.sleep_until_ns
            period = round(PERIOD_S * 1e9)
            start = servo.clock.now_ns()
            t0 = time.process_time_ns()
            for k, v in enumerate(u.tolist()):
                sleep_until(start + k * period)  # the servo's time passes as in the session: the same physics
                exchange(v, slot=k)  # as the session calls it
            return (time.process_time_ns() - t0) / u.size / 1e3

    def answer(u: float, *, slot: int) -> Measurement:  # a servo that answers at once, on time
        return Measurement(u, u, False, 0.0, slot * PERIOD_S)

    def answered() -> float:  # the exchange loop's floor with that servo
        with driver_from_url(URL) as servo:
            clock = servo.clock
            period, start = round(PERIOD_S * 1e9), clock.now_ns()
            t0 = time.process_time_ns()
            for k, v in enumerate(u.tolist()):
                clock.sleep_until_ns(start + k * period)
                answer(v, slot=k)
            return (time.process_time_ns() - t0) / u.size / 1e3

    def session(estimator: bool, recording: bool, constant: bool = False) -> Callable[[], float]:
        def run() -> float:
            with tempfile.TemporaryDirectory() as tmp:
                kwargs: dict[str, object] = {}
                if estimator:
                    kwargs["estimator"] = MRGIA(MRGIAConfig())
                if recording:
                    kwargs["recording"] = Path(tmp) / "rec.csv"
                with driver_from_url(URL) as servo:
                    if constant:
                        servo.exchange = answer  # type: ignore[method-assign]
                    t0 = time.process_time_ns()
                    run_session(servo, u, SessionConfig(period_s=PERIOD_S), **kwargs)  # type: ignore[arg-type]
                    return (time.process_time_ns() - t0) / u.size / 1e3

        return run

    session(True, True)()  # compile everything first
    return {
        "exchange": _best(exchange, repeat),
        "session": _best(session(False, False), repeat),
        "session+mrgia": _best(session(True, False), repeat),
        "session+mrgia+rec": _best(session(True, True), repeat),
        "answered": _best(answered, repeat),
        "session answered": _best(session(False, False, constant=True), repeat),
    }


# ---- identify at growing lengths (one process per size) -------------------------------------------
def identify_child(samples: int) -> dict[str, float]:
    import tracemalloc

    from servoid.cli._live import history_every
    from servoid.ident.identify import identify

    u, y, config = _paper_record(samples, seed=1)
    su, sy, _ = _paper_record(2000, seed=2)
    identify(su, sy, config)  # compiled and warm
    every = history_every(samples)  # the MRGIA's history as `servoid identify` keeps it (every sample: 64 B/sample)
    t0 = time.process_time()
    identify(u, y, config, record_every=every)
    elapsed = time.process_time() - t0
    # memory in a second run, traced (NumPy reports its arrays to tracemalloc): the peak above what was
    # allocated when it started; the process's ru_maxrss cannot tell, generating the record peaked higher
    tracemalloc.start()
    start = tracemalloc.get_traced_memory()[0]
    identify(u, y, config, record_every=every)
    peak = tracemalloc.get_traced_memory()[1] - start
    tracemalloc.stop()
    return {"time": elapsed, "peak": float(peak)}


def identify_rows(sizes: list[int], repeat: int) -> dict[int, dict[str, float]]:
    out: dict[int, dict[str, float]] = {}
    for n in sizes:
        best: dict[str, float] = {}
        for _ in range(repeat if n <= 100_000 else 1):
            res = subprocess.run([sys.executable, __file__, "--identify-child", str(n)],
                                 capture_output=True, text=True, check=True)  # fmt: skip
            r = json.loads(res.stdout)
            best = r if not best else {"time": min(best["time"], r["time"]), "peak": min(best["peak"], r["peak"])}
        out[n] = best
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3, help="rounds, the rows taking turns (default 3)")
    parser.add_argument("--repeat", type=int, default=3, help="runs per row per round (default 3)")
    parser.add_argument("--update-samples", type=int, default=20_000)
    parser.add_argument("--batch-samples", type=int, default=1_000_000)
    parser.add_argument("--session-samples", type=int, default=5_000)
    parser.add_argument("--full", action="store_true", help="identify() up to 10^7 samples (minutes, GBs)")
    parser.add_argument("--no-identify", action="store_true", help="skip the identify() table")
    parser.add_argument("--only-identify", action="store_true", help="only the identify() table")
    parser.add_argument("--identify-child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.identify_child:
        print(json.dumps(identify_child(args.identify_child)))
        return 0
    if not args.only_identify:
        hot_paths(args)
    if args.no_identify:
        return 0
    identify_table(args)
    return 0


def hot_paths(args: argparse.Namespace) -> None:
    """Measure and print the hot paths' table."""
    rows: dict[str, float] = {}
    for _ in range(max(1, args.rounds)):
        for part in (update_rows(args.update_samples, args.repeat), session_rows(args.session_samples, args.repeat)):
            rows.update({k: min(v, rows.get(k, math.inf)) for k, v in part.items()})
        for k, v in batch_rows(args.batch_samples, args.repeat).items():
            rows[k] = max(v, rows.get(k, 0.0))
    load = os.getloadavg()[0]
    ex = rows["exchange"]
    hot = [
        ["MRGIA.update (us)", f"{rows['update']:.3f}", f"{rows['update floor']:.3f}", "bare compiled call, 1 array + 2 floats",
         f"{rows['update'] / rows['update floor']:.2f}", "<= 0.5 us"],
        ["batch replay (M samples/s)", f"{rows['batch']:.2f}", f"{rows['batch numpy']:.0f}", "numpy pass u @ y",
         f"{rows['batch numpy'] / rows['batch']:.0f}", ">= 10 M/s"],
        ["", "", f"{rows['batch loop']:.0f}", "compiled loop over u, y",
         f"{rows['batch loop'] / rows['batch']:.0f}", ""],
    ]  # fmt: skip
    for name, key in (("session, own work (us)", "session"), ("  + MRGIA fed", "session+mrgia"),
                      ("  + recording written", "session+mrgia+rec")):  # fmt: skip
        own = rows[key] - ex
        hot.append([name, f"{own:.2f}", f"{ex:.2f}", "driver.exchange loop", f"{rows[key] / ex:.2f}", "<= 5 us"])
    own, ans = rows["session answered"] - rows["answered"], rows["answered"]
    hot.append(["  (servo answering at once)", f"{own:.2f}", f"{ans:.2f}", "that servo's loop",
                f"{rows['session answered'] / ans:.2f}", "diagnostic"])  # fmt: skip
    table(f"hot paths against their floors, best of {args.rounds} x {args.repeat} runs (load average {load:.2f} "
          f"on {os.cpu_count()} cores, a machine shared with others' runs; ratio: the slower over the faster)",
          ["path", "this", "floor", "floor is", "ratio", "target"], hot)  # fmt: skip


def identify_table(args: argparse.Namespace) -> None:
    """Measure and print identify() at growing lengths."""
    sizes = [1_000, 10_000, 100_000, 1_000_000] + ([10_000_000] if args.full else [])
    ident = identify_rows(sizes, args.repeat)
    out, prev = [], None
    for n, r in ident.items():
        slope = "" if prev is None else f"{math.log(r['time'] / ident[prev]['time']) / math.log(n / prev):.2f}"
        out.append([f"{n:.0e}", f"{r['time']:.3f}", f"{r['peak'] / 1e6:.1f}", f"{r['peak'] / n:.0f}", slope,
                    f"{n / r['time'] / 1e6:.2f}"])  # fmt: skip
        prev = n
    table(f"identify() on the paper's plant at SNR 43, one fresh process per size (load average {os.getloadavg()[0]:.2f})",
          ["samples", "time s", "peak MB added", "bytes/sample", "slope", "M samples/s"], out)  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
