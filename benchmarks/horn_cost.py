"""Where the live answer's horn stage spends its wall time (issue 15: ``refine_online``'s step 5).

Run: ``.venv/bin/python benchmarks/horn_cost.py DIR [DIR ...]`` on the runs ``benchmarks/online.py --keep DIR``
kept (each a ``recording.csv`` and a ``model.json`` of ``servoid identify --driver URL``).

On each live record (from its first usable sample, the unusable readings masked, as the live answer
reads it) step 5's two stages are run as the answer runs them: the massless ``fit_loop(load=False)`` on
the whole record (``--load-stage``: ``fit_loop(load=None)``, as step 5 ran it before), then ``with_horn``
on its answer. Printed per stage: wall seconds, model simulations
(the fits' evaluations: a Jacobian costs one per free parameter), and, per helper of
``ident/offline/loop_fit.py`` that the stages call, its calls, seconds and evaluations; and the wall
time of one free run of the massless and of the horn model on the whole record. The machine may be
shared: the load is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from servoid.cli._live import recording_valid
from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.horn_contact import with_horn
from servoid.recording import read_recording

#: loop_fit's helpers timed (each a module global the stages call by name).
TIMED = ("_search", "_scan", "_fit", "_final_fit", "_last_window", "_holds_on_tail", "_run_load_stage", "floor_rivals")


def _timed(spent: dict[str, list[float]], name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        row = spent[name]
        row[0] += 1
        row[1] += time.perf_counter() - t0
        prob = out[1] if name == "_fit" and isinstance(out, tuple) else None
        row[2] += getattr(prob, "evaluations", 0)
        return out

    return wrapper


def live_record(run: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, dict, int]:
    """A kept run's record as the live answer reads it: ``u, y, keep`` from its first usable sample (the unusable
    readings masked, ``y`` held there), the period (s), its ``model.json`` and that first sample's index."""
    rec = read_recording(run / "recording.csv")
    meta = json.loads((run / "model.json").read_text())
    valid = recording_valid(rec)
    first = int(np.argmax(valid))
    u, y, keep = np.asarray(rec.u)[first:], np.asarray(rec.y)[first:], valid[first:]
    return u, np.where(keep, y, y[0]), keep, float(rec.metadata["period_s"]), meta, first


def profile(run: Path, load: bool | None) -> None:
    u, y, keep, period, meta, _ = live_record(run)
    refined = (meta.get("online_loop") or {}).get("refined") or {}
    fast_s = (refined.get("search") or {}).get("seconds")
    print(f"\n{run.name}: {u.size} samples ({int((~keep).sum())} unusable), slow phase {meta.get('slow_samples')}, "
          f"the fast part's search {fast_s if fast_s is None else f'{fast_s:.1f}'} s, step 5 then: {refined.get('horn')}")  # fmt: skip
    spent: dict[str, list[float]] = defaultdict(lambda: [0, 0.0, 0])
    saved = {name: getattr(lf, name) for name in TIMED}
    for name, fn in saved.items():
        setattr(lf, name, _timed(spent, name, fn))
    try:
        t0 = time.perf_counter()
        whole = lf.fit_loop(u, y, period, keep=keep, load=load)
        t1 = time.perf_counter()
        search = dict(spent)
        spent.clear()
        found = with_horn(u, y, period, whole, keep)
        t2 = time.perf_counter()
    finally:
        for name, fn in saved.items():
            setattr(lf, name, fn)
    print(
        f"  fit_loop(load={load}): {t1 - t0:.1f} s, {whole.evaluations} simulations, {whole.structure} {whole.play:.5f}"
    )
    for name, (calls, s, ev) in search.items():
        print(f"    {name:16s} {calls:3.0f} calls {s:6.1f} s" + (f" {ev:5.0f} evaluations" if ev else ""))
    kept = found is not whole and found.model.compliant
    print(f"  with_horn: {t2 - t1:.1f} s, {found.evaluations - whole.evaluations} simulations, "
          f"{'kept' if kept else 'not kept'} {found.play:.5f}" + (f" al {found.model.al:.3g}" if kept else ""))  # fmt: skip
    for name, (calls, s, ev) in spent.items():
        print(f"    {name:16s} {calls:3.0f} calls {s:6.1f} s" + (f" {ev:5.0f} evaluations" if ev else ""))
    centre = float(np.mean(u))
    for label, model in (("massless", whole.model), ("horn", found.model)):
        t = time.perf_counter()
        for _ in range(5):
            model.simulate(u - centre, y0=float(y[0]) - centre)
        print(f"  one free run of the {label} model on {u.size} samples: {1e3 * (time.perf_counter() - t) / 5:.1f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--load-stage", action="store_true", help="the search with its load stage (load=None)")
    args = parser.parse_args()
    print(f"machine load (1 min): {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores", file=sys.stderr)
    for run in args.runs:
        profile(run, None if args.load_stage else False)
    print(f"machine load (1 min) at the end: {os.getloadavg()[0]:.2f}", file=sys.stderr)


if __name__ == "__main__":
    main()
