"""The motor-side twins' play error split (issue 12): its bias, its noise draw and its set points, and the levers.

Run: ``.venv/bin/python benchmarks/motor_spread.py --presets odrive,cia402 --rates 10,20,50 --seeds 1,2
[--noise-seeds 11,12,13,14] [--length 1.5] [--amplitude 2] [--accel 2] [--set loop_fit.SEARCH_SAMPLES=0]
[--dump out.jsonl]``; ``--load a.jsonl,b.jsonl`` prints dumps' tables again.

Each record is ``real_servos.twin_record``'s (the table's gentle sines, 4096 counts, 0.3 count of noise): ``seed``
draws the set points (the sines, ``seed + 1000``) and, as in the table, the encoders' noise; each of
``--noise-seeds`` draws the encoders' noise again (both encoders: the motor's feeds the drive's loop, so the motion
changes too) over the same set points. ``identify`` with no flags answers, as in the table.

The levers, each a multiple of the table's design (1: the table's record): ``--length`` the record's seconds and its
cap of samples (40 s, 12 000), ``--amplitude`` the sines' amplitude (their reversals fewer at the same acceleration),
``--accel`` their peak acceleration (more reversals at the same amplitude). ``--set MODULE.NAME=VALUE`` (several
separated by ``;``) sets a constant of ``servoid.ident.offline.MODULE`` for the run (the fit's levers; the record is
the same).

Per preset and rate: the records, those within the issue's target (5 % motor side, 15 % play in the loop), the
places named, the mean gap, its sd over all records, the sd over noise draws
(pooled over the set points drawn more than once), the sd over set points (the variance of the set points' mean gaps
less the noise's share in them, ``noise var * mean(1 / draws)``, 0 when below), the median interval half-width relative to the play and how many intervals cover the truth.
The machine may be shared: times are one run each.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import warnings
from typing import Any

import numpy as np
from _table import append_json, table
from real_servos import TARGET, run, twin_record


def one(name: str, mult: float, seed: int, noise: int | None, design: tuple[float, float, float]) -> dict[str, Any]:
    """``identify``'s answer on one record: gap, interval relative to the truth, verdict, samples, seconds."""
    rec = twin_record(name, mult, 1.0, "sines", seed, noise_seed=noise, design=design)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result, seconds = run(np.asarray(rec["u"]), np.asarray(rec["y"]), float(rec["period"]))  # type: ignore[arg-type]
    play = float(rec["play"])  # type: ignore[arg-type]
    lo, hi = result.play_interval
    u = np.asarray(rec["u"])
    turns = int(np.sum(np.diff(np.sign(np.diff(u))) != 0))
    return {
        "preset": name, "mult": mult, "seed": seed, "noise": noise, "design": list(design),
        "samples": int(u.size), "turns": turns, "gap": result.play / play - 1.0,
        "lo": lo / play if math.isfinite(lo) else None, "hi": hi / play if math.isfinite(hi) else None,
        "identifiable": bool(result.identifiable), "structure": result.structure, "s": seconds,
        "mu": float(result.loop.model.mu) if result.loop is not None else None,
        "target": TARGET[str(rec["structure"])],
        "place": "undetermined" if result.verdict.structure_undetermined else (
            "named" if result.structure == rec["structure"] else "WRONG"),
    }  # fmt: skip


def split(rows: list[dict[str, Any]]) -> dict[str, float]:
    """One group's numbers: mean, sd, sd over noise draws, sd over set points (see the module's docstring)."""
    gaps = np.array([r["gap"] for r in rows])
    by_seed: dict[tuple[float, int], list[float]] = {}  # a set point: the rate and the seed
    for r in rows:
        by_seed.setdefault((r["mult"], r["seed"]), []).append(r["gap"])
    repeated = [np.array(g) for g in by_seed.values() if len(g) > 1]
    dof = sum(g.size - 1 for g in repeated)
    noise_var = sum(float(np.sum((g - g.mean()) ** 2)) for g in repeated) / dof if dof else math.nan
    means = np.array([np.mean(g) for g in by_seed.values()])
    share = float(np.mean([1.0 / len(g) for g in by_seed.values()]))
    spread = float(np.var(means, ddof=1)) if means.size > 1 else math.nan
    point_var = max(0.0, spread - share * noise_var) if math.isfinite(noise_var) else math.nan
    halves = [0.5 * (r["hi"] - r["lo"]) / (1.0 + r["gap"]) for r in rows if r["lo"] is not None]
    covers = sum(1 for r in rows if r["lo"] is not None and r["lo"] <= 1.0 <= r["hi"])
    return {
        "n": gaps.size, "within": sum(1 for r in rows if abs(r["gap"]) <= r.get("target", 0.05)),
        "named": sum(1 for r in rows if r.get("place") == "named"), "mean": float(gaps.mean()),
        "sd": float(gaps.std(ddof=1)) if gaps.size > 1 else math.nan, "noise sd": math.sqrt(noise_var),
        "noise dof": dof, "point sd": math.sqrt(point_var),
        "points": " ".join(f"{m:g}x s{k} {100 * np.mean(g):+.1f}/{100 * np.std(g, ddof=1):.1f}"
                           for (m, k), g in by_seed.items() if len(g) > 1), "largest": float(np.abs(gaps).max()),
        "half": float(np.median(halves)) if halves else math.nan, "covers": covers, "intervals": len(halves),
    }  # fmt: skip


def _pct(v: float, sign: bool = False) -> str:
    return "" if not math.isfinite(v) else (f"{100 * v:+.1f} %" if sign else f"{100 * v:.1f} %")


def print_tables(rows: list[dict[str, Any]]) -> None:
    """The per-record table and the split per design, preset and rate (and per design and preset, all rates)."""
    table(
        "identify on each record (noise own: the table's draw; interval relative to the truth)",
        ["preset", "design (len, amp, acc)", "set", "rate", "seed", "noise", "samples", "turns", "gap", "95 %",
         "mu", "place", "verdict", "s"],
        [[r["preset"], ",".join(f"{v:g}" for v in r["design"]), r.get("set", ""), f"{r['mult']:g}x", str(r["seed"]),
          "own" if r["noise"] is None else str(r["noise"]), str(r["samples"]), str(r["turns"]),
          _pct(r["gap"], True), f"[{r['lo']:.3f}, {r['hi']:.3f}]" if r["lo"] is not None else "none",
          f"{r['mu']:.2f}" if r.get("mu") is not None else "", r.get("place", ""),
          "identifiable" if r["identifiable"] else "withheld", f"{r['s']:.1f}"] for r in rows],
    )  # fmt: skip
    out = []
    keys = dict.fromkeys((tuple(r["design"]), r.get("set", ""), r["preset"], r["mult"]) for r in rows)
    pooled = dict.fromkeys((d, s, p, math.inf) for d, s, p, _ in keys)
    for design, setting, name, mult in [*keys, *pooled]:
        group = [r for r in rows if (tuple(r["design"]), r.get("set", ""), r["preset"]) == (design, setting, name)
                 and (mult == math.inf or r["mult"] == mult)]  # fmt: skip
        s = split(group)
        out.append([name, ",".join(f"{v:g}" for v in design), setting, "all" if mult == math.inf else f"{mult:g}x",
                    str(s["n"]), str(s["within"]), str(s["named"]), _pct(s["mean"], True), _pct(s["sd"]),
                    f"{_pct(s['noise sd'])} ({s['noise dof']})", _pct(s["point sd"]), _pct(s["largest"]),
                    _pct(s["half"]), f"{s['covers']} of {s['intervals']}", s["points"]])  # fmt: skip
    table(
        "The split (noise sd: pooled over the set points drawn again, its degrees of freedom; set-point sd: the set "
        "points' means' variance less the noise's share)",
        ["preset", "design", "set", "rate", "records", "within target", "named", "mean", "sd", "noise sd (dof)", "set-point sd",
         "largest", "half-width", "covers", "per set point drawn again: mean/sd %"],
        out,
    )  # fmt: skip


def _apply(settings: str) -> list[tuple[Any, str, Any]]:
    """Set ``MODULE.NAME=VALUE`` constants of ``servoid.ident.offline``; returns what to restore."""
    undo = []
    for item in (s.strip() for s in settings.split(";") if s.strip()):
        target, _, value = item.partition("=")
        module_name, _, name = target.strip().rpartition(".")
        module = importlib.import_module(f"servoid.ident.offline.{module_name}")
        if not hasattr(module, name):
            raise SystemExit(f"--set: {module_name}.{name} is not a constant of servoid.ident.offline.{module_name}")
        old = getattr(module, name)
        undo.append((module, name, old))
        setattr(module, name, type(old)(json.loads(value.strip().lower())))
    return undo


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="odrive,cia402")
    ap.add_argument("--rates", default="10,20,50")
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--noise-seeds", default="", help="more noise draws of each record (comma-separated)")
    ap.add_argument("--only-own", default="", help="SEEDS: the seeds whose records get only their own noise draw")
    ap.add_argument("--length", type=float, default=1.0, help="the record's seconds and samples, x the table's")
    ap.add_argument("--amplitude", type=float, default=1.0, help="the sines' amplitude, x the table's")
    ap.add_argument("--accel", type=float, default=1.0, help="the sines' peak acceleration, x the table's")
    ap.add_argument("--set", default="", help="MODULE.NAME=VALUE;...: constants of servoid.ident.offline")
    ap.add_argument("--dump", default=None)
    ap.add_argument("--load", default=None, help="comma-separated dumps to print again")
    args = ap.parse_args()
    if args.load:
        rows = []
        for path in args.load.split(","):
            with open(path) as f:
                rows += [json.loads(line) for line in f if line.strip()]
        print_tables(rows)
        return
    for flag in ("length", "amplitude", "accel"):
        if not getattr(args, flag) > 0.0:
            ap.error(f"--{flag} (={getattr(args, flag)!r}) must be > 0")
    _apply(args.set)
    design = (args.length, args.amplitude, args.accel)
    only_own = {int(s) for s in args.only_own.split(",") if s.strip()}
    noises = [int(n) for n in args.noise_seeds.split(",") if n.strip()]
    rows = []
    for name in args.presets.split(","):
        for mult in (float(m) for m in args.rates.split(",")):
            for seed in (int(s) for s in args.seeds.split(",")):
                for noise in [None, *([] if seed in only_own else noises)]:
                    rows.append({**one(name, mult, seed, noise, design), "set": args.set})
                    print(json.dumps(rows[-1]), flush=True)
                    append_json(args.dump, rows[-1])
    print_tables(rows)


if __name__ == "__main__":
    main()
