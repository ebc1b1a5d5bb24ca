"""Window refits that hold a horn, replayed on kept live records (issue 15, stswin19).

Run: ``.venv/bin/python benchmarks/horn_windows.py DIR [DIR ...] [--sources answer first at20 sofar10]`` on the live
runs ``benchmarks/online.py --presets sts3215 --seeds 0 1 2 3 --keep KEEP`` kept (``DIR``: ``KEEP/sts3215-0-S``).

The live windows of a horn servo are massless (``ident/online/window.py``); the answer is the horn stage on the whole
record (``refine_online``'s step 5). Per run, the fast part's windows as the live run has them (its first 10 s, then
every 5 s, the last 30 s at most, the first second not scored, and the stream's end) are refitted warm
(:func:`~servoid.ident.offline.loop_fit.refit_loop`, the window's 10 evaluations: the play and the loop refitted, the
horn's inertia ratio, restitution, friction and contact held) with a horn taken from ``--sources``:

* ``answer``: the answer's own horn (step 5 on the whole record; not there during the run: a bound);
* ``first``: the horn stage on the first window's search (``fit_loop(load=None)`` on the fast part's first 10 s,
  then ``with_horn`` on it), held from that window on;
* ``at20``: the same on the window at 20 s (the second look's);
* ``sofar10``: step 5 on the record so far (the slow phase and the fast part's first 10 s), held from the window
  at 15 s on.

Each source's horn is held twice: on the massless window estimate's loop and play (what the windows would refit), and
on the source's own model. Printed: the live windows' plays against the answer (from the run's history), each chain's
plays against the answer and its median wall time per refit, and the last window's profile over the play with the
source's horn held (the play held at ``--grid`` times the answer, the loop refitted from the massless estimate's with
20 evaluations; the lowest point and each point's cost over it). ``--whole``: also the whole record (the slow phase
and the fast part, its first second not scored) refitted warm with the source's horn held on the massless estimate,
and its profile's lowest point. The machine may be shared: the load is printed.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import numpy as np
from horn_cost import live_record  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers.twin import preset
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.offline.horn_contact import with_horn
from servoid.ident.offline.loop_fit import fit_loop, refit_loop
from servoid.ident.online.refinement import _fast_start
from servoid.ident.online.window import BURN_IN_S, EVERY_S, FIRST_S, MAX_NFEV, WINDOW_S

#: The horn's parameters a window holds (the rest of :func:`refit_loop`'s are refitted).
HORN = ("mu", "e", "al", "wc", "zeta")
#: The true play of the STS3215 twin (c1 + c2), rad (the twin's own).
TRUTH = preset("sts3215").play_rad
#: Evaluations of each profile point's refit.
PROFILE_NFEV = 20

Window = tuple[float, np.ndarray, np.ndarray, np.ndarray]


def windows(u: np.ndarray, y: np.ndarray, keep: np.ndarray, head: int, period: float) -> list[Window]:
    """The live run's windows of the fast part (from ``head``): ``(t_s, u, y, score)`` each, the stream's end last."""
    n_fast = u.size - head
    ends = [int(round(t / period)) for t in np.arange(FIRST_S, n_fast * period, EVERY_S)]
    if not ends or ends[-1] != n_fast:
        ends.append(n_fast)
    out = []
    for e in ends:
        hi = head + e
        lo = max(head, hi - int(round(WINDOW_S / period)))
        score = keep[lo:hi].copy()
        score[: int(round(BURN_IN_S / period))] = False
        out.append((e * period, u[lo:hi], y[lo:hi], score))
    return out


def chain(wins: list[Window], start: ServoLoopModel) -> tuple[list[float], list[float]]:
    """Warm refits of ``wins`` in turn from ``start`` (its horn held): the plays and the wall seconds of each."""
    plays, secs, m = [], [], start
    for _, u, y, score in wins:
        t0 = time.perf_counter()
        m = refit_loop(u, y, m, score=score, max_nfev=MAX_NFEV).model
        secs.append(time.perf_counter() - t0)
        plays.append(m.play)
    return plays, secs


def horn_of(u: np.ndarray, y: np.ndarray, keep: np.ndarray, period: float, *, window: bool) -> ServoLoopModel | None:
    """``fit_loop`` then ``with_horn`` on a record, as a first window searches (``window``: ``load=None``, every
    rival) or as step 5 does (``load=False``): the kept horn's model, None when the stage does not keep one."""
    found = (fit_loop(u, y, period, keep=keep, load=None, light_rivals=False) if window
             else fit_loop(u, y, period, keep=keep, load=False))  # fmt: skip
    horned = with_horn(u, y, period, found, keep)
    return horned.model if horned is not found and horned.model.compliant else None


def profile(win: Window, base: ServoLoopModel, plays: np.ndarray) -> np.ndarray:
    """The window's free-run NRMSE with the play held at each of ``plays``, the rest of ``base`` refitted (horn held)."""
    _, u, y, score = win
    return np.array([refit_loop(u, y, dataclasses.replace(base, c1=p / 2, c2=p / 2), score=score,
                                max_nfev=PROFILE_NFEV, hold=("play",)).fit_nrmse for p in plays])  # fmt: skip


def report(run: Path, sources: list[str], grid: list[float], whole: bool = False) -> None:
    """One kept run: the live windows, then each source's held horn."""
    u, y, keep, period, meta, first = live_record(run)
    head = _fast_start(keep, max(int(meta.get("slow_samples") or 0) - first, 0))
    wins = windows(u, y, keep, head, period)
    answer = float(meta["answer"]["play"])
    loop = meta["online_loop"]
    est = ServoLoopModel.from_dict(loop["estimate"]["model"])
    rel = " ".join
    print(f"== {run.name}: answer {answer / TRUTH - 1:+.1%} of the truth; windows at "
          f"{rel(f'{w[0]:.1f}' for w in wins)} s of the fast part; plays against the answer")  # fmt: skip
    live = (f"{r['t_s']:.0f} s {r['play'] / answer - 1:+.1%}" for r in loop["estimate"]["history"])
    print(f"   live (massless): {rel(live)}")
    for src in sources:
        t0 = time.perf_counter()
        if src == "answer":
            model, at = ServoLoopModel.from_dict(loop["refined"]["model"]), 0
        elif src in ("first", "at20"):
            t_s = FIRST_S if src == "first" else 20.0
            at = next(i for i, w in enumerate(wins) if w[0] >= t_s - 1e-9)
            _, wu, wy, _ = wins[at]
            lo = head + int(round(wins[at][0] / period)) - wu.size
            model = horn_of(wu, wy, keep[lo : lo + wu.size], period, window=True)
        elif src == "sofar10":
            n = head + int(round(FIRST_S / period))
            model, at = horn_of(u[:n], y[:n], keep[:n], period, window=False), 1
        else:
            raise SystemExit(f"--sources: {src!r} is not one of answer, first, at20, sofar10")
        found_s = time.perf_counter() - t0
        if model is None or not model.compliant:
            print(f"   {src:8s}: no horn kept ({found_s:.1f} s)")
            continue
        horn = {k: getattr(model, k) for k in HORN}
        held = dataclasses.replace(est, **horn)
        said = f"al {model.al:.1f}, wc {model.wc:.0f}, zeta {model.zeta:.3f}; its play {model.play / answer - 1:+.1%}"
        print(f"   {src:8s}: horn {said} ({found_s:.1f} s), held from {wins[at][0]:.0f} s")
        for name, start in (("on the window estimate", held), ("on its own model", model)):
            plays, secs = chain(wins[at:], start)
            print(f"      {name:23s}: {rel(f'{p / answer - 1:+.1%}' for p in plays)}   "
                  f"{1e3 * float(np.median(secs)):.0f} ms a refit (max {1e3 * max(secs):.0f})")  # fmt: skip
        costs = profile(wins[-1], held, np.array(grid) * answer)
        low = float(costs.min())
        print(f"      last window, play held (x answer): lowest at {grid[int(np.argmin(costs))]:.2f}; "
              f"{rel(f'{g:.2f}:{c / low - 1:+.1%}' for g, c in zip(grid, costs))}")  # fmt: skip
        if whole:
            score = keep.copy()
            score[: int(round(BURN_IN_S / period))] = False
            record = (u.size * period, u, y, score)
            (play,), _ = chain([record], held)
            costs = profile(record, held, np.array(grid) * answer)
            print(f"      the whole record: warm {play / answer - 1:+.1%}, play held: lowest at "
                  f"{grid[int(np.argmin(costs))]:.2f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+", help="kept run directories (online.py --keep)")
    parser.add_argument("--sources", nargs="+", default=["answer", "first", "at20", "sofar10"])
    parser.add_argument("--grid", type=float, nargs="+", default=[0.85, 0.9, 0.95, 1.0, 1.05, 1.1, 1.15])
    parser.add_argument("--whole", action="store_true", help="also the whole record scored, the horn held")
    args = parser.parse_args()
    print(f"machine load (1 min): {os.getloadavg()[0]:.2f}")
    for run in args.runs:
        report(run, args.sources, args.grid, args.whole)
    print(f"machine load (1 min) at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
