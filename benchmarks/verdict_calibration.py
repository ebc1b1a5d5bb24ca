"""The verdict's calibration (issues 12, 15): dump every rule's numbers per run, then score rules without refitting.

Run (two steps; the first fits, the second only reads the dumps):

``.venv/bin/python benchmarks/verdict_calibration.py fit --set calibration --out benchmarks/verdict_dumps``
``.venv/bin/python benchmarks/verdict_calibration.py fit --set holdout --out benchmarks/verdict_dumps``
``.venv/bin/python benchmarks/verdict_calibration.py score benchmarks/verdict_dumps/*.jsonl``

Sets (the twins of ``benchmarks/real_servos.py``, 4096-count encoders, 0.3 count of noise):

- ``calibration``: seeds 3-6; presets odrive, cia402, xm430, sts3215; gentle sines at 5, 10, 20, 50,
  100x the loop bandwidth; the wrong-answer generators on seeds 3-4: friction x4 at 20x, held steps
  at 20x and 50x (every preset); and the real recordings of ``/work/shared/data`` (EMPS, BAM), which
  must all stay withheld.
- ``holdout``: seeds 1-2, the same presets, gentle sines at 10, 20, 50x (the table the rules were
  not calibrated on).

``fit`` writes one JSON line per run (``<set>.jsonl``): the truth, the answer, the verdict as identify gave
it, and every number a rule reads (the play; fit_loop's interval and the black box's; identify's reported
interval; the fit, the record's estimated floor and the floor of its resolution; the noise estimate and
the residual's white share; the margin, place statistic, dead time, stall band, reversals, the load stage's
inertia ratio; the doubts identify added). The answer's residual goes to ``<set>.npz`` beside it (not
committed; scoring reads the JSON only). A set already partly dumped resumes where it stopped. The
calibration set took 24 min of identify on a loaded machine (load 5-10 on 2 cores), the holdout 5.

``score`` rebuilds each run's :class:`~servoid.ident.offline.intervals.Evidence` from the dump with the
rules of the code it runs with (:func:`~servoid.ident.offline.intervals.reported_interval`,
:func:`~servoid.ident.offline.intervals.verdict`) and prints, per set, the confusion of the verdict as
dumped ("old") and as rescored ("new") -- identifiable right / identifiable WRONG / withheld right /
withheld WRONG -- and the coverage of the intervals each reports. Right: the true structure and |gap|
within the issue's target (5 % motor side, 15 % play in the loop, 25 % on held steps); a real recording
has no truth and must be withheld.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from real_servos import STEPS_TARGET, TARGET, recordings, right, run, twin_record

from servoid.ident.identify import PLACED_MARGIN, Identification
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import intervals
from servoid.ident.offline.intervals import Evidence, noise_std, play_interval, quantum, resolution_floor_nrmse

PRESETS = ("odrive", "cia402", "xm430", "sts3215")


def grid(which: str) -> list[tuple[str, float, float, str, int]]:
    """The twin runs of a set: (preset, rate x bandwidth, friction factor, kind, seed)."""
    if which == "holdout":
        return [(p, r, 1.0, "sines", s) for p in PRESETS for r in (10.0, 20.0, 50.0) for s in (1, 2)]
    runs = [(p, r, 1.0, "sines", s) for p in PRESETS for r in (5.0, 10.0, 20.0, 50.0, 100.0) for s in (3, 4, 5, 6)]
    runs += [(p, 20.0, 4.0, "sines", s) for p in PRESETS for s in (3, 4)]
    runs += [(p, r, 1.0, "steps", s) for p in PRESETS for r in (20.0, 50.0) for s in (3, 4)]
    return runs


def _num(x: Any) -> float | None:
    """A finite float or None (JSON has no NaN)."""
    if x is None:
        return None
    v = float(x)
    return v if math.isfinite(v) else None


def _pair(p: tuple[float, float]) -> list[float | None]:
    return [_num(p[0]), _num(p[1])]


def dump(result: Identification, u: np.ndarray, y: np.ndarray) -> tuple[dict[str, Any], np.ndarray]:
    """Every number the verdict's rules read, from one identify answer (and the answer's residual)."""
    loop = result.loop
    scale = float(np.std(y))
    bb_interval = play_interval(float(result.model.dead_zone), float(result.play_stderr))
    if loop is not None:
        residual = y - np.asarray(loop.simulated, dtype=np.float64)
        fit = float(loop.fit_nrmse)
        noise_interval = (float(loop.play_interval[0]), float(loop.play_interval[1]))
    else:
        from servoid.ident.models.simulate import free_run  # noqa: PLC0415 - the black box's answer only

        try:
            residual = y - free_run(result.model, u, y0=float(y[0]))
        except Exception:  # noqa: BLE001 - an approximate residual only feeds the white share
            residual = np.full_like(y, np.nan)
        fit = float(result.fit_nrmse)
        noise_interval = bb_interval
    model = getattr(loop, "model", None)
    evidence = Evidence(
        play=float(result.play), interval=result.play_interval, reversals=int(result.reversals), fit_nrmse=fit,
        floor=float(result.floor_nrmse),
        margin=None if loop is None else float(loop.margin),
        dead_time_samples=None if loop is None else loop.dead_time_samples,
        stall_band=None if loop is None else float(loop.stall_band),
        residual_white=None if loop is not None else (None if result.refinement is None else result.residual_white),
        interval_note=result.interval_note,
        place_z=float(loop.place_z) if loop is not None and loop.structure == PLAY_IN_LOOP else None,
        **({"structure": result.structure} if "structure" in Evidence.__dataclass_fields__ else {}),
    )  # fmt: skip
    own = set(intervals.verdict(evidence).reasons)
    row = {
        "structure": result.structure, "form": result.form, "play": float(result.play),
        "interval": _pair(result.play_interval), "interval_note": result.interval_note,
        "noise_interval": _pair(noise_interval), "bb_interval": _pair(bb_interval), "bb_play": float(result.model.dead_zone),
        "fit": fit, "bb_fit": float(result.fit_nrmse), "floor": _num(result.floor_nrmse),
        "resolution_floor": _num(resolution_floor_nrmse(y)), "noise_std": float(noise_std(y)),
        "quantum": float(quantum(y)), "scale": scale,
        "residual_rms": float(np.sqrt(np.mean(np.square(residual - np.mean(residual))))),
        "white_std": _num(white_std(residual)),
        "margin": None if loop is None else float(loop.margin),
        "place_z": None if loop is None else _num(loop.place_z),
        "dead_time_samples": None if loop is None or loop.dead_time_samples is None else float(loop.dead_time_samples),
        "stall_band": None if loop is None else float(loop.stall_band),
        "reversals": int(result.reversals), "residual_white": bool(result.residual_white),
        "massive": bool(getattr(model, "massive", False)), "mu": _num(getattr(model, "mu", None)) if model else None,
        "loop_reasons": list(loop.reasons) if loop is not None else [],
        "doubts": [r for r in result.verdict.reasons if r not in own and (loop is None or r not in loop.reasons)],
        "identifiable": bool(result.identifiable), "reasons": list(result.verdict.reasons),
    }  # fmt: skip
    return row, residual


def white_std(residual: np.ndarray) -> float:
    """The residual's white share, ``sqrt(gamma_0 - gamma_1)`` of its autocovariance (a measurement for the dumps).

    White noise puts all its variance at lag 0; a model error that changes slowly against the sample
    rate is nearly as large at lag 1. On the motor-side twins (white residuals at their floor) it came out
    0.97-1.03 times the twins' true noise, on the STS3215 twin at 5-20x 1.08-1.31 times (the horn's bounce).
    """
    r = np.asarray(residual, dtype=np.float64)
    r = r[np.isfinite(r)] - float(np.mean(r[np.isfinite(r)]))
    if r.size < 3:
        return math.nan
    return float(np.sqrt(max(float(np.mean(r * r) - np.mean(r[1:] * r[:-1])), 0.0)))


def real_records() -> list[tuple[str, np.ndarray, np.ndarray, float | None]]:
    """The real recordings of ``real_servos.recordings`` that are present, read."""
    from servoid.readers import read  # noqa: PLC0415

    out = []
    for label, path, options in recordings():
        if path.is_file():
            rec = read(path, options)  # type: ignore[arg-type]
            period = float(np.median(np.diff(rec.t))) if rec.t is not None else None
            out.append((label, np.asarray(rec.u, dtype=np.float64), np.asarray(rec.y, dtype=np.float64), period))
    return out


def fit(which: str, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    lines = out / f"{which}.jsonl"
    arrays: dict[str, np.ndarray] = {}
    done = {json.loads(line)["label"] for line in lines.read_text().splitlines()} if lines.is_file() else set()
    jobs: list[tuple[str, dict[str, Any], Any]] = []
    for name, mult, friction, kind, seed in grid(which):
        label = f"{name} {kind} {mult:g}x x{friction:g} s{seed}"
        head = {"label": label, "preset": name, "kind": kind, "rate": mult, "friction": friction, "seed": seed}
        jobs.append((label, head, (name, mult, friction, kind, seed)))
    if which == "calibration":
        for label, u, y, period in real_records():
            jobs.append((label, {"label": label, "preset": "real", "kind": "real"}, (u, y, period)))
    for label, head, spec in jobs:
        if label in done:
            continue
        if head["kind"] == "real":
            u, y, period = spec
            truth: dict[str, Any] = {"true_structure": None, "true_play": None}
        else:
            rec = twin_record(*spec[:4], spec[4])
            u, y, period = rec["u"], rec["y"], rec["period"]
            truth = {
                "true_structure": rec["structure"],
                "true_play": float(rec["play"]),
                "twin_floor": float(rec["floor"]),
            }  # type: ignore[arg-type]
        started = time.perf_counter()
        try:
            result, _ = run(u, y, period)
        except Exception as exc:  # noqa: BLE001 - a benchmark records what happened and goes on
            row = {**head, **truth, "error": str(exc)[:200]}
        else:
            row, residual = dump(result, np.asarray(u, dtype=np.float64), np.asarray(y, dtype=np.float64))
            row = {**head, **truth, **row}
            if truth["true_play"] is not None:
                row["right"] = right(rec, result, head["kind"])
            arrays[label] = residual
        row["seconds"] = time.perf_counter() - started
        with lines.open("a") as f:
            f.write(json.dumps(row) + "\n")
        if len(arrays) % 10 == 0 and arrays:
            _save(out / f"{which}.npz", arrays)
        print(label, row.get("reasons", row.get("error")), f"{row['seconds']:.1f} s", flush=True)
    if arrays:
        _save(out / f"{which}.npz", arrays)


def _save(npz: Path, arrays: dict[str, np.ndarray]) -> None:
    old = dict(np.load(npz)) if npz.is_file() else {}
    np.savez_compressed(npz, **{**old, **arrays})


# -- scoring ----------------------------------------------------------------------------------------
def is_right(row: dict[str, Any], play: float, structure: str) -> bool:
    """The true structure and |gap| within the issue's target (a real recording: never right to identify)."""
    if row.get("true_play") is None:
        return False
    target = STEPS_TARGET if row["kind"] == "steps" else TARGET[row["true_structure"]]
    gap = play / row["true_play"] - 1.0
    return structure == row["true_structure"] and math.isfinite(gap) and abs(gap) <= target


def _f(x: float | None) -> float:
    return math.nan if x is None else float(x)


def model_error_floor(row: dict[str, Any], white_floor: bool) -> float:
    """The floor (absolute, unit of y) below which identify's interval counts the residual as noise.

    identify's: the record's resolution alone (:func:`~servoid.ident.offline.intervals.resolution_floor_nrmse`).
    ``white_floor`` (tried, dropped; README, issue 12 verdict session): the residual's white share, at most
    the record's noise estimate, at least the resolution's ``q / sqrt(12)``.
    """
    resolution = _f(row["resolution_floor"]) * row["scale"]
    if not white_floor or row.get("white_std") is None:
        return resolution
    return max(resolution, min(float(row["white_std"]), float(row["noise_std"])))


def rescore(
    row: dict[str, Any], white_floor: bool = False, placed_waives: bool = False
) -> tuple[bool, tuple[float, float], tuple[str, ...]]:
    """The verdict and the reported interval the current code's rules give on a dumped run.

    ``white_floor``: see :func:`model_error_floor`. ``placed_waives`` (tried, dropped): the dead-time and
    stall-band rules waived where the place of the play is named by the place test (a play-in-loop answer at
    :data:`~servoid.ident.offline.intervals.PLACE_Z` or more) or by :data:`~servoid.ident.identify.PLACED_MARGIN`.
    """
    scale = row["scale"]
    noise = (_f(row["noise_interval"][0]), _f(row["noise_interval"][1]))
    floor = model_error_floor(row, white_floor) / scale
    q = row["quantum"]
    interval = intervals.reported_interval(
        noise, intervals.model_error_halfwidth(row["fit"], floor, scale), row["play"], q,
        intervals.dither_noise(row["noise_std"], q),
    )  # fmt: skip
    # the rival's play the place doubts took into the hull (identify widens the interval to it)
    dumped = (_f(row["interval"][0]), _f(row["interval"][1]))
    expected = intervals.with_model_error(
        noise, intervals.model_error_halfwidth(row["fit"], _f(row["resolution_floor"]), scale)
    )
    if all(map(math.isfinite, dumped)) and all(map(math.isfinite, interval)):
        if dumped[0] < expected[0] - 1e-12:
            interval = (min(interval[0], dumped[0]), interval[1])
        if dumped[1] > expected[1] + 1e-12:
            interval = (interval[0], max(interval[1], dumped[1]))
    note = row["interval_note"]
    if note is not None:
        interval = (math.nan, math.nan)
    loop = row["margin"] is not None
    placed = loop and (
        (row["structure"] == PLAY_IN_LOOP and _f(row["place_z"]) >= intervals.PLACE_Z) or row["margin"] >= PLACED_MARGIN
    )
    waived = placed_waives and placed
    evidence = Evidence(
        play=row["play"], interval=interval, reversals=row["reversals"], fit_nrmse=row["fit"], floor=_f(row["floor"]),
        margin=row["margin"], dead_time_samples=None if waived else row["dead_time_samples"],
        stall_band=None if waived else row["stall_band"],
        residual_white=None if loop else row["residual_white"], interval_note=note,
        place_z=_f(row["place_z"]) if row["structure"] == PLAY_IN_LOOP and loop else None,
        structure=row["structure"],
    )  # fmt: skip
    doubts = tuple(r for r in row["doubts"] if r not in row["loop_reasons"])
    every = (*intervals.verdict(evidence).reasons, *doubts, *row["loop_reasons"])
    return not every, interval, every


def score(paths: list[Path], white_floor: bool = False, placed_waives: bool = False) -> None:
    for path in paths:
        rows = [json.loads(line) for line in path.read_text().splitlines()]
        rows = [r for r in rows if "error" not in r]
        print(f"\n{path.name}: {len(rows)} runs")
        for which in ("old", "new"):
            cells: dict[str, list[str]] = {}
            covered = reported = 0
            for r in rows:
                if which == "old":
                    ok, interval, why = r["identifiable"], (_f(r["interval"][0]), _f(r["interval"][1])), r["reasons"]
                else:
                    ok, interval, why = rescore(r, white_floor, placed_waives)
                good = is_right(r, r["play"], r["structure"])
                cell = f"{'identifiable' if ok else 'withheld'} {'right' if good else 'WRONG'}"
                short = ",".join(sorted({w.split(" ")[0] + " " + w.split(" ")[1] for w in why}))[:80]
                gap = "" if r["true_play"] is None else f"{100 * (r['play'] / r['true_play'] - 1):+.1f} %"
                rel = (
                    f"[{interval[0] / r['true_play']:.2f}, {interval[1] / r['true_play']:.2f}]"
                    if r["true_play"] and all(map(math.isfinite, interval))
                    else ""
                )
                cells.setdefault(cell, []).append(f"{r['label']} {gap} {rel} ({short})")
                if r["true_play"] is not None and all(map(math.isfinite, interval)):
                    reported += 1
                    covered += interval[0] <= r["true_play"] <= interval[1]
            print(f" {which} rules: intervals covering the truth {covered} of {reported}")
            groups: dict[str, list[int]] = {}
            for r in rows:
                ok, interval, _ = (
                    (r["identifiable"], (_f(r["interval"][0]), _f(r["interval"][1])), ())
                    if which == "old"
                    else rescore(r, white_floor, placed_waives)
                )
                kind = r["kind"] if r["kind"] != "sines" or r.get("friction", 1.0) == 1.0 else "sines fr x4"
                g = groups.setdefault(f"{r['preset']} {kind}", [0, 0, 0, 0, 0, 0])
                good = is_right(r, r["play"], r["structure"])
                reported_here = r["true_play"] is not None and all(map(math.isfinite, interval))
                g[0] += 1
                g[1] += good
                g[2] += ok and good
                g[3] += ok and not good
                g[4] += reported_here and interval[0] <= r["true_play"] <= interval[1]
                g[5] += reported_here
            for name, (n, good, ir, iw, cov, rep) in groups.items():
                print(
                    f"   {name:24s} runs {n:3d}  right {good:3d}  identifiable right {ir:2d} WRONG {iw:2d}  "
                    f"intervals covering {cov:2d} of {rep:2d}"
                )
            for cell in ("identifiable right", "identifiable WRONG", "withheld right", "withheld WRONG"):
                runs = cells.get(cell, [])
                print(f"  {cell}: {len(runs)}")
                if which == "new" and cell.startswith("identifiable"):
                    for label in runs:
                        print(f"    {label}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    f = sub.add_parser("fit", help="run identify on a set and dump the rules' numbers")
    f.add_argument("--set", choices=("calibration", "holdout"), required=True)
    f.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "verdict_dumps")
    s = sub.add_parser("score", help="score the dumped runs with the dumped and the current rules")
    s.add_argument("paths", nargs="+", type=Path)
    s.add_argument(
        "--white-floor",
        action="store_true",
        help="rescore with the residual's white share as the model-error floor (tried and dropped)",
    )
    s.add_argument(
        "--placed-waives",
        action="store_true",
        help="rescore with the dead-time and stall rules waived where the place is named (tried and dropped)",
    )
    args = ap.parse_args()
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    if args.command == "fit":
        fit(args.set, args.out)
    else:
        score(args.paths, args.white_floor, args.placed_waives)


if __name__ == "__main__":
    sys.exit(main())
