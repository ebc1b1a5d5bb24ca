"""The servo-loop fit's time with its Jacobian's columns on one thread and on the shared pool.

Runs :func:`servoid.ident.offline.loop_fit.fit_loop` on the twins' records of
``real_servos.py`` (gentle sines at 20x the loop bandwidth, seed 1) once with
``SERVOID_THREADS=1`` (the serial path: the floor, measured in the same run) and
once with the default rule (the CPUs this process may use), best of
``--repeat`` rounds each, and checks that both give the same answer to the bit
(each column is the same simulation, wherever it runs)::

    .venv/bin/python benchmarks/loop_threads.py [--twins cia402,sts3215,xm430] [--repeat 2]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _table import table
from real_servos import twin_record

from servoid.ident.offline import _threads
from servoid.ident.offline.loop_fit import LoopChoice, fit_loop


def _timed(rec: dict[str, object], threads: str | None, repeat: int) -> tuple[float, LoopChoice]:
    if threads is None:
        os.environ.pop(_threads.ENV, None)
    else:
        os.environ[_threads.ENV] = threads
    best, choice = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        choice = fit_loop(rec["u"], rec["y"], float(rec["period"]), seed=1)  # type: ignore[arg-type]
        best = min(best, time.perf_counter() - t0)
    assert choice is not None
    return best, choice


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--twins", default="cia402,sts3215,xm430")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    user = os.environ.get(_threads.ENV)
    os.environ.pop(_threads.ENV, None)
    pool = _threads.threads()
    rows = []
    loads = [os.getloadavg()[0]]
    for name in args.twins.split(","):
        rec = twin_record(name, 20.0, 1.0, "sines", 1)
        fit_loop(rec["u"][:400], rec["y"][:400], float(rec["period"]))  # type: ignore[index]  # compile outside the clock
        serial, a = _timed(rec, "1", args.repeat)
        threaded, b = _timed(rec, None, args.repeat)
        same = a.structure == b.structure and a.evaluations == b.evaluations and a.params.keys() == b.params.keys()
        for x, y in [(a.simulated, b.simulated), (a.play_interval, b.play_interval), (a.play, b.play),
                     (list(a.params.values()), list(b.params.values()))]:  # fmt: skip
            same = same and np.array_equal(x, y, equal_nan=True)
        rows.append([name, str(len(np.asarray(rec["u"]))), f"{serial:.2f}", f"{threaded:.2f}",
                     f"{serial / threaded:.2f}", str(a.evaluations), "yes" if same else "NO"])  # fmt: skip
        loads.append(os.getloadavg()[0])
    if user is not None:
        os.environ[_threads.ENV] = user
    table(
        f"fit_loop, serial Jacobian vs {pool} threads (best of {args.repeat}; load average {min(loads):.2f}-"
        f"{max(loads):.2f} on {os.cpu_count()} cores, a machine shared with others' runs)",
        ["twin", "samples", "serial s", "threaded s", "speed-up", "evaluations", "same answer"],
        rows,
    )


if __name__ == "__main__":
    main()
