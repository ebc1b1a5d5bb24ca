"""The cost over the play, everything else refitted, of the massless and the horn model (issue 12/15, hornstable18).

Run: ``.venv/bin/python benchmarks/horn_profile.py --runs DIR [DIR ...] [--ends 15 20 25 0]`` on the live runs
``benchmarks/online.py --keep DIR`` kept (refine_online's step 5 on the slow phase plus the fast part's first
``--ends`` seconds; 0: all), or ``--table`` for the STS3215 table records (``real_servos.py``'s sines, 1x friction,
``--rates``, ``--seeds``).

Per record (end): the massless search (``fit_loop(load=False)`` on a live record, as step 5 runs it; ``load=None``
on a table record, as identify runs it) and the horn stage (``with_horn``), their plays and intervals against the
truth; then the profile: the play held at ``--grid`` times the truth, every other parameter of the model refitted
on every kept sample (from the answer's values, and from the neighbouring grid point's fit: the lower cost kept),
its cost over the answer's own cost on the same samples (``cost / cost_answer - 1``, %) and in the answer's
residual variances (``(cost - cost_answer) / (cost_answer / n)``). A profile point below the answer's cost is a
lower minimum the search missed; a profile that rises by a few variances only over the grid is a cost that cannot
tell the plays apart. The machine may be shared: the load is printed.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from servoid.drivers.twin import preset
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import horn_contact as hc
from servoid.ident.offline import loop_fit as lf

#: Truth plays (c1 + c2) of the horn presets, rad (the twins' own: one owner of the fact).
TRUTH = {name: preset(name).play_rad for name in ("sts3215", "xm430")}
#: The horn stage's own profile over the play, as the module has it.
PLAY_PROFILE = hc.PLAY_PROFILE


def _live(run: Path, end_s: float, back: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, str]:
    """A kept live record as refine_online reads it, cut at the fast part's first ``end_s`` s (0: all; ``back``: cut
    ``end_s`` s before the record's end, whatever the design's phases)."""
    from horn_cost import live_record

    u, y, keep, period, meta, first = live_record(run)
    slow = max(int(meta.get("slow_samples") or 0) - first, 0)
    if back:
        n = max(u.size - int(round(end_s / period)), 1)
    else:
        n = u.size if end_s <= 0 else min(u.size, slow + int(round(end_s / period)))
    return u[:n], y[:n], keep[:n], period, run.name.split("-")[0]


def live_ends(runs: list[Path], ends: list[float], back: bool = False) -> Iterator[tuple[Path, float, tuple[Any, ...]]]:
    """Every kept live record cut at every end (:func:`_live`), its header printed first: ``(run, end, record)``."""
    print(f"machine load (1 min): {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores", flush=True)
    for run in runs:
        for end in ends:
            record = _live(run, end, back)
            where = f"{end:g} s before the end" if back else f"fast part to {end or 'the end'} s"
            print(f"{run.name} {where} ({record[0].size} samples):", flush=True)
            yield run, end, record


def _held_fit(
    u: np.ndarray, y: np.ndarray, period: float, d: dict[str, float], free: tuple[str, ...], kept: np.ndarray,
    a_scale: float, integrator: bool, play: float,
) -> tuple[dict[str, float], float]:  # fmt: skip
    """``d`` refitted with its play held at ``play`` (horn_contact.held_play_fit, a longer fit), and its cost on ``kept``."""
    fitted, cost, _ = hc.held_play_fit(u, y, period, d, play, kept, a_scale, integrator, free,
                                       max_nfev=lf.FINAL_NFEV + lf.CANDIDATE_NFEV)  # fmt: skip
    return fitted, cost


def profile(
    u: np.ndarray,
    y: np.ndarray,
    kept: np.ndarray,
    period: float,
    truth: float,
    grid: list[float],
    load: bool | None,
    no_stage_profile: bool = False,
) -> None:
    """Print the answers and the two models' profiles over the play on one record."""
    t0 = time.perf_counter()
    hc.PLAY_PROFILE = () if no_stage_profile else PLAY_PROFILE
    whole = lf.fit_loop(u, y, period, keep=kept, load=load)
    found = hc.with_horn(u, y, period, whole, kept)
    spent = time.perf_counter() - t0
    kept_horn = found is not whole and found.model.compliant

    def said(c: lf.LoopChoice) -> str:
        lo, hi = c.play_interval
        cover = "covers" if lo <= truth <= hi else "MISSES"
        return f"{c.play / truth - 1:+.1%} [{lo / truth:.3f}, {hi / truth:.3f}] {cover}"

    print(f"  massless {whole.structure}: {said(whole)}; horn {'kept' if kept_horn else 'not kept'}: "
          f"{said(found) if kept_horn else '-'} [{spent:.1f} s]")  # fmt: skip
    if whole.structure != PLAY_IN_LOOP or not grid:
        return
    centre = float(np.mean(u))
    uc, yc = np.ascontiguousarray(u - centre), np.ascontiguousarray(y - centre)
    _, kv = lf._linear_start(uc, yc, period)
    a_scale = 0.1 * kv * float(np.std(np.diff(yc))) / period
    n = int(np.count_nonzero(kept))
    models = [("massless", whole.model, lf._free(PLAY_IN_LOOP, whole.model.ki > 0.0))]
    if kept_horn:
        models.append(("horn", found.model, lf._free(PLAY_IN_LOOP, found.model.ki > 0.0) + hc.HORN))
    for name, model, free in models:
        d = hc._values(model)
        base = lf._cost(uc, yc, period, PLAY_IN_LOOP, d, kept)
        t1 = time.perf_counter()
        rows = []
        prev: dict[str, float] | None = None
        # from the answer's play outwards on both sides, each point also started from its neighbour's fit
        order = sorted(grid, key=lambda g: abs(g * truth - model.play))
        fits: dict[float, tuple[dict[str, float], float]] = {}
        for g in order:
            near = min(fits, key=lambda h: abs(h - g), default=None)
            prev = fits[near][0] if near is not None else None
            best = _held_fit(uc, yc, period, d, free, kept, a_scale, model.ki > 0.0, g * truth)
            if prev is not None:
                other = _held_fit(uc, yc, period, prev, free, kept, a_scale, model.ki > 0.0, g * truth)
                best = min(best, other, key=lambda f: f[1])
            fits[g] = best
        for g in sorted(fits):
            cost = fits[g][1]
            rows.append(f"{g:.2f}: {cost / base - 1:+.2%} ({(cost - base) / (base / n):+.0f})")
        low = min(fits, key=lambda g: fits[g][1])
        print(f"    {name} at {model.play / truth:.3f}x: profile (play/truth: cost vs the answer's, % (variances)) "
              f"{'  '.join(rows)}; lowest at {low:.2f}x [{time.perf_counter() - t1:.0f} s]")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=Path, nargs="*", default=[], help="online.py --keep run directories")
    parser.add_argument("--ends", type=float, nargs="+", default=[15.0, 20.0, 25.0, 0.0], help="fast part's s; 0: all")
    parser.add_argument("--back", action="store_true", help="--ends count back from the record's end (any design)")
    parser.add_argument("--table", action="store_true", help="the STS3215 table records (real_servos.py sines)")
    parser.add_argument("--preset", default="sts3215")
    parser.add_argument("--rates", type=float, nargs="+", default=[10.0, 20.0, 50.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--grid", type=float, nargs="*", default=[0.8, 0.85, 0.9, 0.95, 1.0, 1.05, 1.1],
                        help="plays / truth of the profile (none: the answers only)")  # fmt: skip
    parser.add_argument("--no-stage-profile", action="store_true", help="the horn stage without its own profile")
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    for _, _, (u, y, kept, period, name) in live_ends(args.runs, args.ends, args.back):
        profile(u, y, kept, period, TRUTH[name], args.grid, False, args.no_stage_profile)
        sys.stdout.flush()
    if args.table:
        import real_servos

        for mult in args.rates:
            for seed in args.seeds:
                rec = real_servos.twin_record(args.preset, mult, 1.0, "sines", seed)
                u, y = np.asarray(rec["u"]), np.asarray(rec["y"])
                print(f"{args.preset} sines {mult:g}x seed {seed} ({u.size} samples):", flush=True)
                profile(u, y, np.ones(u.size, dtype=bool), float(rec["period"]), TRUTH[args.preset], args.grid, None,
                        args.no_stage_profile)  # fmt: skip
    print(f"machine load (1 min) at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
