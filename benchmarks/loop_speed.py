"""The servo-loop fit's time and answers, and ``identify``'s wall time: another revision's loop fit against this tree's, in the same run.

Runs ``servoid.ident.identify`` (the user's call: the black box, the servo-loop fit
and its load stage where it runs) on the twins' records of ``real_servos.py``
(gentle sines at 20x the loop bandwidth, seed 1, and one 20 000-sample record of
the CiA 402 twin, 50 s at 400 Hz) twice: once with the servo-loop fit
(:mod:`~servoid.ident.offline.loop_fit`) of the git revision ``--against`` (default
``main``, read with ``git show``) and once with this tree's. The rest of the code is this
tree's in both rows (the kernels, the thread pool, ``identify`` itself): a change there shows
in both, and its time is measured against another tree's process, not here. Both on the
thread rule's default (``SERVOID_THREADS`` to change it); best of ``--repeat``. The table gives ``identify``'s wall time, the servo-loop fit's
own time and simulations, the place of the play, the play's error against the twin's
truth, its 95 % interval over the truth and the loop fit over the record's floor, so
that a faster path that moves the answer shows::

    .venv/bin/python benchmarks/loop_speed.py [--twins cia402,sts3215,xm430,cia402@20000] [--repeat 2] [--against main]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import types
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import real_servos
from _table import table
from real_servos import run, twin_record

from servoid.ident.identify import Identification
from servoid.ident.offline import loop_fit


@contextlib.contextmanager
def _loop_fit_of(revision: str) -> Iterator[None]:
    """``servoid.ident.offline.loop_fit`` replaced by the module of ``revision`` (its callers import it at call time)."""
    source = subprocess.run(
        ["git", "show", f"{revision}:ident/offline/loop_fit.py"],
        cwd=Path(__file__).resolve().parent,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    name = loop_fit.__name__
    module = types.ModuleType(name)
    module.__file__ = f"{revision}:ident/offline/loop_fit.py"
    package = sys.modules[name.rpartition(".")[0]]
    sys.modules[name] = module
    try:
        exec(compile(source, module.__file__, "exec"), module.__dict__)
        package.loop_fit = module  # type: ignore[attr-defined]
        yield
    finally:
        sys.modules[name] = loop_fit
        package.loop_fit = loop_fit  # type: ignore[attr-defined]


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


def _timed(rec: dict[str, object], repeat: int) -> tuple[float, Identification]:
    """``identify``'s best wall time of ``repeat`` runs on ``rec``, and its answer."""
    best, result = np.inf, None
    for _ in range(repeat):
        result, seconds = run(rec["u"], rec["y"], float(rec["period"]))  # type: ignore[arg-type]
        best = min(best, seconds)
    assert result is not None
    return best, result


def _row(spec: str, path: str, rec: dict[str, object], seconds: float, r: Identification) -> list[str]:
    truth = float(rec["play"])  # type: ignore[arg-type]
    c = r.loop
    if c is None:
        return [spec, str(len(np.asarray(rec["u"]))), path, f"{seconds:.2f}", "-", "-", "(no loop fit)", "", "", "", ""]
    lo, hi = c.play_interval
    return [spec, str(len(np.asarray(rec["u"]))), path, f"{seconds:.2f}", f"{c.seconds:.2f}", str(c.evaluations),
            c.structure, f"{100 * (c.play / truth - 1):+.1f} %", f"[{lo / truth:.2f}, {hi / truth:.2f}]",
            f"{c.fit_nrmse / float(rec['floor']):.2f}", f"{c.margin:.3f}"]  # type: ignore[arg-type]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--twins", default="cia402,sts3215,xm430,cia402@20000")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--against", default="main", help="the git revision whose loop fit runs first")
    args = parser.parse_args()
    rows = []
    loads = [os.getloadavg()[0]]
    for spec in args.twins.split(","):
        rec = _record(spec)
        run(rec["u"][:400], rec["y"][:400], float(rec["period"]))  # type: ignore[index, arg-type]  # compile outside the clock
        with _loop_fit_of(args.against):
            main_s, a = _timed(rec, args.repeat)
        own_s, b = _timed(rec, args.repeat)
        rows.append(_row(spec, args.against, rec, main_s, a))
        rows.append(_row(spec, f"now ({main_s / own_s:.1f}x)", rec, own_s, b))
        loads.append(os.getloadavg()[0])
    table(
        f"identify, {args.against}'s loop fit against this tree's (best of {args.repeat}; load average {min(loads):.2f}-"
        f"{max(loads):.2f} on {os.cpu_count()} cores, a machine shared with others' runs)",
        ["twin", "samples", "path", "identify s", "loop fit s", "simulations", "structure", "play error",
         "95 % / truth", "fit/floor", "margin"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
