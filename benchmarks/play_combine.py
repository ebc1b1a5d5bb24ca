"""Is the motor-side play steadier combined over several searches, or read at its profile's centre (issue 12)?

Run: ``.venv/bin/python benchmarks/play_combine.py --presets odrive,cia402 --rates 10,20,50 --seeds 1,2,3,4,5,6
[--fit-seeds 0,1,2,3] [--dump out.jsonl]``; ``--load out.jsonl`` prints the tables of a dump again.

On each record (``real_servos.twin_record``: the table's gentle sines, 4096 counts, 0.3 count of
noise), centred as ``identify`` centres it, :func:`~servoid.ident.offline.loop_fit.fit_loop` as
``identify`` runs it (``load=None``) with each ``--fit-seeds`` seed (the jitter of the play grid its
scan starts from: another search path on the same record). Each answer's cost on every sample is
given in residual variances above the lowest of the record's answers (the lowest cost over the
samples; under 3.84, the 95 % likelihood-ratio bound of one parameter, the record does not tell two
answers apart; the residuals are correlated, so it is a bound, not a test). From them, the answers
combined:

- ``seed 0``: the first search (``identify``'s answer today);
- ``lowest``: the answer with the lowest cost on every sample;
- ``median``: the median play of the answers;
- ``tied median``: the median play of the answers within 3.84 variances of the lowest;
- ``weighted``: the plays weighted by ``exp(-cost / 2)`` (cost in variances above the lowest);
- ``lowest if clear``: seed 0 unless another answer costs more than 3.84 variances less;
- ``profile centre``: seed 0's profile: its play held at :data:`PROFILE` times its own, every other free
  parameter refitted on every sample from the answer (the final refit's budget and stopping rule), and the
  vertex of a parabola in ``ln(play)`` through the five costs (kept inside the held plays).

The summary gives each estimator's gaps over the records: how many within 5 %, their mean, standard deviation
and largest, and the time it costs (the searches' time added up; the profile's over the first search's).
The twins are not changed. Printed as measured (the machine may be shared: times are one run each).
"""

from __future__ import annotations

import argparse
import json
import math
import time
import warnings
from collections import defaultdict
from typing import Any

import numpy as np
from _table import table
from play_at_truth import refit_setup
from real_servos import twin_record

from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.operating_point import operating_point

#: The profile's held plays, as multiples of the answer's.
PROFILE = (0.85, 0.92, 1.08, 1.15)
#: The 95 % likelihood-ratio bound of one parameter (chi-square, one degree of freedom), in residual variances.
LR95 = 3.84


def profile_centre(
    u: np.ndarray, y: np.ndarray, period: float, choice: lf.LoopChoice, factors: tuple[float, ...] = PROFILE
) -> tuple[float, list[float], float]:
    """The vertex of the answer's profile at ``factors`` times its play (in the unit of ``y``), the profile's costs in
    residual variances above the answer's, and its seconds."""
    t0 = time.perf_counter()
    model = choice.model
    uc, yc, a_scale, free, answer = refit_setup(u, y, period, model)
    integrator = model.ki > 0.0
    held = tuple(n for n in free if n != "play")
    every = np.ones(yc.size, dtype=bool)
    base = lf._cost(uc, yc, period, model.structure, answer, every)
    costs = [0.0]
    for factor in factors:
        d, _, _ = lf._fit(uc, yc, period, model.structure, dict(answer, play=factor * answer["play"]), every, a_scale,
                          integrator=integrator, max_nfev=lf.FINAL_NFEV, free=held, ftol=lf.FTOL, stall=lf.FINAL_STALL)  # fmt: skip
        costs.append((lf._cost(uc, yc, period, model.structure, d, every) - base) / (base / yc.size))
    x = np.log([1.0, *factors])
    a, b, _ = np.polyfit(x, costs, 2)
    vertex = float(np.clip(-b / (2.0 * a), x.min(), x.max())) if a > 0.0 else 0.0
    return answer["play"] * math.exp(vertex), costs[1:], time.perf_counter() - t0


def record(name: str, mult: float, seed: int, fit_seeds: list[int], factors: tuple[float, ...]) -> dict[str, Any]:
    """One record's answers (gap, cost on every sample, seconds) over the fit seeds, and seed 0's profile centre."""
    rec = twin_record(name, mult, 1.0, "sines", seed)
    u, y = operating_point(rec["u"], rec["y"]).centre(rec["u"], rec["y"])  # type: ignore[arg-type]
    period, truth = float(rec["period"]), float(rec["play"])  # type: ignore[arg-type]
    out: dict[str, Any] = {"preset": name, "mult": mult, "seed": seed, "n": int(y.size), "answers": []}
    for k, fit_seed in enumerate(fit_seeds):
        t0 = time.perf_counter()
        choice = lf.fit_loop(u, y, period, seed=fit_seed, load=None)
        seconds = time.perf_counter() - t0
        r = choice.simulated - y
        out["answers"].append({
            "fit_seed": fit_seed, "gap": choice.play / truth - 1.0, "ssr": float(r @ r), "s": seconds,
            "structure": choice.structure, "mu": choice.model.mu if choice.model.massive else 0.0,
        })  # fmt: skip
        if k == 0:
            play, costs, s = profile_centre(u, y, period, choice, factors)
            out["profile"] = {"gap": play / truth - 1.0, "costs": costs, "s": s, "factors": list(factors)}
    return out


def combined(rec: dict[str, Any]) -> dict[str, float]:
    """Each estimator's gap on one record (see the module)."""
    gaps = np.array([a["gap"] for a in rec["answers"]])
    ssr = np.array([a["ssr"] for a in rec["answers"]])
    over = (ssr - ssr.min()) / (ssr.min() / rec["n"])
    tied = over <= LR95
    weights = np.exp(-0.5 * over)
    return {
        "seed 0": float(gaps[0]),
        "lowest": float(gaps[np.argmin(ssr)]),
        "median": float(np.median(gaps)),
        "tied median": float(np.median(gaps[tied])),
        "weighted": float(np.sum(weights * gaps) / np.sum(weights)),
        "lowest if clear": float(gaps[0] if over[0] <= LR95 else gaps[np.argmin(ssr)]),
        "profile centre": float(rec["profile"]["gap"]),
    }


def report(records: list[dict[str, Any]]) -> None:
    rows = []
    for rec in records:
        ssr = np.array([a["ssr"] for a in rec["answers"]])
        over = (ssr - ssr.min()) / (ssr.min() / rec["n"])
        est = combined(rec)
        rows.append([
            rec["preset"], f"{rec['mult']:g}x", str(rec["seed"]),
            ", ".join(f"{a['gap']:+.1%}" for a in rec["answers"]), ", ".join(f"{o:.1f}" for o in over),
            f"{est['lowest']:+.1%}", f"{est['weighted']:+.1%}", f"{est['profile centre']:+.1%}",
            ", ".join(f"{c:+.0f}" for c in rec["profile"]["costs"]),
        ])  # fmt: skip
    table(
        "fit_loop's answers over its seeds (gap; cost on every sample over the lowest, residual variances) and combined",
        ["preset", "rate", "seed", "answers by fit seed", "cost over lowest", "lowest", "weighted", "profile centre",
         "profile (costs at the held plays)"],
        rows,
    )  # fmt: skip
    summary = []
    by: dict[tuple[str, str], list[float]] = defaultdict(list)
    for rec in records:
        for what, gap in combined(rec).items():
            by[(rec["preset"], what)].append(gap)
    for (name, what), gaps in by.items():
        recs = [r for r in records if r["preset"] == name]
        first = sum(r["answers"][0]["s"] for r in recs)
        if what == "profile centre":
            cost = first + sum(r["profile"]["s"] for r in recs)
        elif what == "seed 0":
            cost = first
        else:
            cost = sum(a["s"] for r in recs for a in r["answers"])
        g = np.array(gaps)
        summary.append([
            name, what, f"{int(np.sum(np.abs(g) <= 0.05))} of {g.size}", f"{np.mean(g):+.1%}", f"{np.std(g):.1%}",
            f"{np.max(np.abs(g)):.1%}", f"{cost / first:.2f}",
        ])  # fmt: skip
    table("Per estimator over the records", ["preset", "estimator", "within 5 %", "mean", "sd", "largest", "time / seed 0's"], summary)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="odrive,cia402")
    ap.add_argument("--rates", default="10,20,50")
    ap.add_argument("--seeds", default="1,2,3,4,5,6")
    ap.add_argument("--fit-seeds", default="0,1,2,3")
    ap.add_argument(
        "--profile", default="", help="the profile's held plays, multiples of the answer's (default: PROFILE)"
    )
    ap.add_argument("--dump", default="", help="append each record's numbers to this JSON-lines file")
    ap.add_argument("--load", default="", help="print the tables of a dump (no fits)")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    if args.load:
        with open(args.load) as fh:
            report([json.loads(line) for line in fh])
        return
    factors = tuple(float(f) for f in args.profile.split(",")) if args.profile else PROFILE
    fit_seeds = [int(s) for s in args.fit_seeds.split(",")]
    records = []
    for name in args.presets.split(","):
        for mult in (float(r) for r in args.rates.split(",")):
            for seed in (int(s) for s in args.seeds.split(",")):
                records.append(record(name, mult, seed, fit_seeds, factors))
                answers = ", ".join(f"{a['gap']:+.1%}" for a in records[-1]["answers"])
                print(name, f"{mult:g}x", seed, answers, f"profile {records[-1]['profile']['gap']:+.1%}", flush=True)
                if args.dump:
                    with open(args.dump, "a") as fh:
                        fh.write(json.dumps(records[-1]) + "\n")
    report(records)


if __name__ == "__main__":
    main()
