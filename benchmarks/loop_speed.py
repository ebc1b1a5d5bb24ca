"""The servo-loop fit's time and answers: the main path's settings against today's, measured in the same run.

Runs :func:`servoid.ident.offline.loop_fit.fit_loop` on the twins' records of
``real_servos.py`` (gentle sines at 20x the loop bandwidth, seed 1, and one
20 000-sample record of the CiA 402 twin, 50 s at 400 Hz) twice: once with the
fit's knobs set as on main before issue 12's speed work (:data:`MAIN`: scipy's
``ftol`` 1e-8 and no stall rule, the two places of the play one after the other; the
floor, measured in the same process) and once with the module's own. Both on the
thread rule's default (``SERVOID_THREADS`` to change it); best of
``--repeat``. The table gives each one's time, simulations, the place of the play,
the play's error against the twin's truth, its 95 % interval over the truth and the
fit over the record's floor, so that a faster path that moves the answer shows::

    .venv/bin/python benchmarks/loop_speed.py [--twins cia402,sts3215,xm430,cia402@20000] [--repeat 2]
"""

from __future__ import annotations

import argparse
import contextlib
import os
from collections.abc import Iterator

import numpy as np
import real_servos
from _table import table
from loop_threads import _timed
from real_servos import twin_record

from servoid.ident.offline import _threads, loop_fit
from servoid.ident.offline.loop_fit import LoopChoice, fit_loop

#: The knobs of :mod:`~servoid.ident.offline.loop_fit` as main had them before the speed work.
MAIN: dict[str, float] = {"FTOL": 1e-8, "STALL": 0.0, "PLACES_AT_ONCE": False}


@contextlib.contextmanager
def _knobs(values: dict[str, float]) -> Iterator[None]:
    old = {k: getattr(loop_fit, k) for k in values}
    for k, v in values.items():
        setattr(loop_fit, k, v)
    try:
        yield
    finally:
        for k, v in old.items():
            setattr(loop_fit, k, v)


def _record(spec: str) -> dict[str, object]:
    """``name`` (20x, the benchmark's length) or ``name@samples`` (20x, as many samples, the duration stretched)."""
    name, _, samples = spec.partition("@")
    if not samples:
        return twin_record(name, 20.0, 1.0, "sines", 1)
    old = real_servos.DURATION_S, real_servos.MAX_SAMPLES
    n = int(samples)
    real_servos.DURATION_S, real_servos.MAX_SAMPLES = n / (20.0 * real_servos.BANDWIDTH_HZ[name]), n
    try:
        return twin_record(name, 20.0, 1.0, "sines", 1)
    finally:
        real_servos.DURATION_S, real_servos.MAX_SAMPLES = old


def _row(spec: str, path: str, rec: dict[str, object], seconds: float, c: LoopChoice) -> list[str]:
    truth = float(rec["play"])  # type: ignore[arg-type]
    lo, hi = c.play_interval
    return [spec, str(len(np.asarray(rec["u"]))), path, f"{seconds:.2f}", str(c.evaluations), c.structure,
            f"{100 * (c.play / truth - 1):+.1f} %", f"[{lo / truth:.2f}, {hi / truth:.2f}]",
            f"{c.fit_nrmse / float(rec['floor']):.2f}", f"{c.margin:.3f}"]  # type: ignore[arg-type]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--twins", default="cia402,sts3215,xm430,cia402@20000")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    threads = os.environ.get(_threads.ENV)  # the user's thread rule, kept
    rows = []
    loads = [os.getloadavg()[0]]
    for spec in args.twins.split(","):
        rec = _record(spec)
        fit_loop(rec["u"][:400], rec["y"][:400], float(rec["period"]))  # type: ignore[index]  # compile outside the clock
        with _knobs(MAIN):
            main_s, a = _timed(rec, threads, args.repeat)
        own_s, b = _timed(rec, threads, args.repeat)
        rows.append(_row(spec, "main", rec, main_s, a))
        rows.append(_row(spec, f"now ({main_s / own_s:.1f}x)", rec, own_s, b))
        loads.append(os.getloadavg()[0])
    table(
        f"fit_loop, main's settings against today's (best of {args.repeat}; load average {min(loads):.2f}-"
        f"{max(loads):.2f} on {os.cpu_count()} cores, a machine shared with others' runs)",
        ["twin", "samples", "path", "s", "simulations", "structure", "play error", "95 % / truth", "fit/floor",
         "margin"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
