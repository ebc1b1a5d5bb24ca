"""Which of a twin's effects carries identify's play error (issue 12): one effect switched off at a time.

Run: ``.venv/bin/python benchmarks/twin_effects.py --presets odrive --rates 20,50 --seeds 1,2
[--effects "as is,gear x100 stiffer"] [--noise-seeds own,11] [--fine] [--output-cpr 16384] [--dump out.jsonl
[--resume]]``; ``--load a.jsonl,b.jsonl`` prints dumps' summary again.

Each row is :func:`servoid.ident.identify` as ``real_servos.py`` runs it (no structure flags) on
the same gentle-sines record (``real_servos.twin_record``: same excitation seed, same noise seed)
from the twin with one of its effects switched off or scaled: the gear contact (compliance,
damping, losses), the load (inertia, friction; ``load x0.01``: a hundredth of both), the motor's
friction (its break-away hump, its viscous part, all of it; ``friction x0.01``: the motor's and the load's),
the motor's back-EMF (``back-EMF off``: a millionth of it, which the current loop no longer has to overcome),
the drive (its velocity estimate: filter or encoder PLL, scaled or off;
its current loop; its loop rate; the loop encoder's resolution) and the output encoder (its noise
off or doubled, 4 or 16 times its counts; ``--output-cpr`` reads every record with that many counts
per revolution; ``--fine`` with 2**20 counts and no noise, so that the model's own error shows above
the floor). ``--duration-s`` runs each record longer (or shorter) than the table's 40 s. ``--noise-seeds``
draws the encoders' noise from each of those seeds on every record (the same excitation): the spread of the answers over them is what the record's resolution and noise
alone leave, which no model can remove. Each row gives the play in the output encoder's counts and the 95 %
interval over the truth. The last table gives each effect's play errors over the records, their mean,
standard deviation and largest, how many are within 5 % and how many intervals cover the truth: an effect
that carries the error moves all records towards 0, not one; its last column is the change record by record against
``as is`` on the same records (its mean and standard error), when the run (or the dumps read) holds ``as is``.
``--dump`` appends each row to a JSON-lines file; ``--resume`` takes the rows already there instead of running them.
The twins' physics and presets are not changed (only this run's copies, through the preset's
overrides). The machine may be shared: times are one run each.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
import real_servos
from _table import append_json, table
from real_servos import run, twin_record

from servoid.drivers.twin import preset
from servoid.errors import ConfigError


def effects(name: str) -> dict[str, dict[str, object]]:
    """The twin's effects, each as the preset's overrides that switch it off or scale it (a stiffer gear's faster ring gets the sub-steps it needs)."""
    b = preset(name)
    cases: dict[str, dict[str, object]] = {
        "as is": {},
        "gear x100 stiffer": {"gear_stiffness_nm_rad": 100 * b.gear_stiffness_nm_rad, "gear_damping_nms": 10 * b.gear_damping_nms},
        "gear damping x5": {"gear_damping_nms": 5 * b.gear_damping_nms},
        "gear lossless": {"gear_efficiency": 1.0},
        "load inertia x0.1": {"load_inertia_kgm2": 0.1 * b.load_inertia_kgm2},
        "load friction x0.1": {"load_coulomb_nm": 0.1 * b.load_coulomb_nm, "load_breakaway_nm": 0.1 * b.load_breakaway_nm, "load_viscous_nms": 0.1 * b.load_viscous_nms},
        "load viscous 0": {"load_viscous_nms": 0.0},
        "load break-away = Coulomb": {"load_breakaway_nm": b.load_coulomb_nm},
        "motor hump off": {"motor_breakaway_nm": b.motor_coulomb_nm},
        "motor friction x0.01": {"motor_coulomb_nm": 0.01 * b.motor_coulomb_nm, "motor_breakaway_nm": 0.01 * b.motor_breakaway_nm, "motor_viscous_nms": 0.01 * b.motor_viscous_nms},
        "current loop x3 faster": {"cur_kp_v_a": 3 * b.cur_kp_v_a, "cur_ki_v_as": 3 * b.cur_ki_v_as},
        "current loop x2 faster": {"cur_kp_v_a": 2 * b.cur_kp_v_a, "cur_ki_v_as": 2 * b.cur_ki_v_as},
        "current loop x2 slower": {"cur_kp_v_a": 0.5 * b.cur_kp_v_a, "cur_ki_v_as": 0.5 * b.cur_ki_v_as},
        "loop encoder x64 counts": {"motor_encoder_cpr": 64 * b.motor_encoder_cpr},
        "load inertia x3": {"load_inertia_kgm2": 3 * b.load_inertia_kgm2},
        "load inertia x0.01": {"load_inertia_kgm2": 0.01 * b.load_inertia_kgm2},
        "load friction x0.01": {"load_coulomb_nm": 0.01 * b.load_coulomb_nm, "load_breakaway_nm": 0.01 * b.load_breakaway_nm, "load_viscous_nms": 0.01 * b.load_viscous_nms},
        "load x0.01": {"load_inertia_kgm2": 0.01 * b.load_inertia_kgm2, "load_coulomb_nm": 0.01 * b.load_coulomb_nm, "load_breakaway_nm": 0.01 * b.load_breakaway_nm, "load_viscous_nms": 0.01 * b.load_viscous_nms},
        "no noise": {"encoder_noise_counts": 0.0},
        "noise x2": {"encoder_noise_counts": 2 * real_servos.NOISE_COUNTS},
        "output encoder x4 counts": {"load_encoder_cpr": 4 * 4096},
        "output encoder x16 counts": {"load_encoder_cpr": 16 * 4096},
        # ciabias22: the rest of the twin's effects, one at a time (back-EMF: a millionth of it, the parameter > 0)
        "back-EMF off": {"back_emf_v_s": 1e-6 * b.back_emf_v_s},
        "motor viscous 0": {"motor_viscous_nms": 0.0},
        "gear damping x0.1": {"gear_damping_nms": 0.1 * b.gear_damping_nms},
        "gear damping x0.3": {"gear_damping_nms": 0.3 * b.gear_damping_nms},
        "gear damping x2": {"gear_damping_nms": 2 * b.gear_damping_nms},
        "gear x100 stiffer, damping as is": {"gear_stiffness_nm_rad": 100 * b.gear_stiffness_nm_rad},
        "friction x0.01": {"motor_coulomb_nm": 0.01 * b.motor_coulomb_nm, "motor_breakaway_nm": 0.01 * b.motor_breakaway_nm, "motor_viscous_nms": 0.01 * b.motor_viscous_nms, "load_coulomb_nm": 0.01 * b.load_coulomb_nm, "load_breakaway_nm": 0.01 * b.load_breakaway_nm, "load_viscous_nms": 0.01 * b.load_viscous_nms},
        "break-aways = Coulomb": {"motor_breakaway_nm": b.motor_coulomb_nm, "load_breakaway_nm": b.load_coulomb_nm},
    }  # fmt: skip
    if b.pll_bandwidth_rad_s > 0:
        cases["PLL x2 faster"] = {"pll_bandwidth_rad_s": 2 * b.pll_bandwidth_rad_s}
        cases["PLL x2 faster, loop encoder x64"] = {"pll_bandwidth_rad_s": 2 * b.pll_bandwidth_rad_s, "motor_encoder_cpr": 64 * b.motor_encoder_cpr}  # fmt: skip
    if b.velocity_filter_s > 0:
        cases["velocity filter off"] = {"velocity_filter_s": 0.0}
        cases["velocity filter x0.25"] = {"velocity_filter_s": 0.25 * b.velocity_filter_s}
        cases["velocity filter x2"] = {"velocity_filter_s": 2 * b.velocity_filter_s}
        cases["velocity filter off, load x0.01"] = {"velocity_filter_s": 0.0, **cases["load x0.01"]}
        cases["velocity filter off, gear x100 stiffer"] = {"velocity_filter_s": 0.0, **cases["gear x100 stiffer"]}
    if b.current_rate_hz > b.control_rate_hz:
        cases["loops x5 faster"] = {"control_rate_hz": 5 * b.control_rate_hz}
    for over in cases.values():
        while True:
            try:
                preset(name, **over)  # type: ignore[arg-type]
                break
            except ConfigError:
                over["substeps"] = 2 * int(over.get("substeps", b.substeps))  # type: ignore[call-overload]
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="odrive,cia402")
    parser.add_argument("--rates", default="20")
    parser.add_argument("--seeds", default="1,2")
    parser.add_argument("--effects", default="", help="comma-separated effect names (default: all of the preset's)")
    parser.add_argument("--fine", action="store_true", help="a 2**20-count output encoder without noise")
    parser.add_argument(
        "--noise-seeds",
        default="",
        help="comma-separated seeds of the encoders' noise, each on every record ('own': the record's seed; default: own)",
    )
    parser.add_argument(
        "--duration-s",
        type=float,
        default=real_servos.DURATION_S,
        help="the record's length, s (default: the table's; the table's sample cap scaled with it)",
    )
    parser.add_argument(
        "--output-cpr",
        type=int,
        default=0,
        help="the output encoder's counts per revolution on every record (default: the table's 4096)",
    )
    parser.add_argument("--dump", default=None, help="append each record's answer to this file (JSON lines)")
    parser.add_argument(
        "--resume", action="store_true", help="reuse the rows already in --dump (same preset, effect, rate, seeds)"
    )
    parser.add_argument("--load", default=None, help="comma-separated dumps: print their summary again, run nothing")
    args = parser.parse_args()
    if args.load:
        loaded: dict[tuple[Any, ...], dict[str, Any]] = {}  # a record in two dumps counts once
        for path in args.load.split(","):
            with open(path) as f:
                for row in (json.loads(line) for line in f if line.strip()):
                    loaded[row["preset"], row["effect"], row["mult"], row["seed"], row["noise_seed"], row["counts"]] = (
                        row
                    )
        summarise(list(loaded.values()))
        return
    # a longer record: the table's excitation run on for longer, its sample cap scaled alike
    real_servos.MAX_SAMPLES = round(real_servos.MAX_SAMPLES * args.duration_s / real_servos.DURATION_S)
    real_servos.DURATION_S = args.duration_s
    noise_seeds: list[int | None] = [
        None if s.strip() == "own" else int(s) for s in args.noise_seeds.split(",") if s.strip()
    ] or [None]
    fine: dict[str, object] = {"load_encoder_cpr": 2**20, "encoder_noise_counts": 0.0} if args.fine else {}
    if args.output_cpr:
        fine["load_encoder_cpr"] = args.output_cpr
    rows: list[list[str]] = []
    answers: list[dict[str, Any]] = []
    done: dict[tuple[str, str, float, int, int | None], dict[str, Any]] = {}
    if args.resume and args.dump:
        try:
            with open(args.dump) as f:
                for old in (json.loads(line) for line in f if line.strip()):
                    done[old["preset"], old["effect"], old["mult"], old["seed"], old["noise_seed"]] = old
        except FileNotFoundError:
            pass
    for name in args.presets.split(","):
        cases = effects(name)
        wanted = [e.strip() for e in args.effects.split(",") if e.strip()] or list(cases)
        for what in wanted:
            if what not in cases:
                raise SystemExit(f"effect (={what!r}) must be one of {', '.join(cases)}")
            for mult in (float(r) for r in args.rates.split(",")):
                for seed, noise in ((int(s), n) for s in args.seeds.split(",") for n in noise_seeds):
                    again = done.get((name, what, mult, seed, noise))
                    row = again if again is not None else answer(name, what, mult, seed, noise, {**cases[what], **fine})
                    answers.append(row)
                    rows.append([
                        name, what, f"{mult:g}x", str(seed) if noise is None else f"{seed}/{noise}", row["structure"],
                        f"{row['gap']:+.1%}", f"{row['fit']:.2f}", f"{row['mu']:.2f}", f"{row['counts']:.2f}",
                        f"[{row['lo']:.2f}, {row['hi']:.2f}]" if row["lo"] is not None else "none", f"{row['s']:.1f}",
                    ])  # fmt: skip
                    print(" | ".join(rows[-1]), flush=True)
                    if again is None:
                        append_json(args.dump, row)
    enc = "2**20-count output encoder, no noise" if args.fine else f"{args.output_cpr or 4096} counts, 0.3 count noise"
    table(f"identify on each record, one effect switched off ({enc})", ["preset", "twin", "rate", "seed(/noise)", "structure", "gap", "fit/floor", "mu", "play (counts)", "95 % / truth", "s"], rows)  # fmt: skip
    summarise(answers)


def summarise(answers: list[dict[str, Any]]) -> None:
    """Per preset and effect: the gaps, their mean, sd and largest, how many within 5 %, how many intervals cover; and
    the change record by record against ``as is`` on the same records (rate, seed, noise draw), its mean and standard
    error (the records both ran; none without an ``as is`` row)."""
    gaps: dict[tuple[str, str], list[float]] = {}
    covered: dict[tuple[str, str], int] = {}
    keyed: dict[tuple[str, str], dict[tuple[float, int, int | None], float]] = {}
    for row in answers:
        key = (row["preset"], row["effect"])
        gaps.setdefault(key, []).append(row["gap"])
        covered[key] = covered.get(key, 0) + row["covers"]
        keyed.setdefault(key, {})[row["mult"], row["seed"], row["noise_seed"]] = row["gap"]
    summary = []
    for (name, what), v in gaps.items():
        base = keyed.get((name, "as is"), {})
        diff = [g - base[r] for r, g in keyed[name, what].items() if r in base]
        paired = (
            f"{np.mean(diff):+.1%} ± {np.std(diff, ddof=1) / np.sqrt(len(diff)):.1%} ({len(diff)})"
            if len(diff) > 1 and what != "as is" else ""
        )  # fmt: skip
        summary.append(
            [name, what, f"{np.mean(v):+.1%}", f"{np.std(v, ddof=1) if len(v) > 1 else 0.0:.1%}",
             f"{np.max(np.abs(v)):.1%}", f"{sum(abs(g) <= 0.05 for g in v)} of {len(v)}", f"{covered[name, what]} of {len(v)}",
             paired]
        )  # fmt: skip
    table(
        "Per effect over the records (vs as is: the mean change record by record ± its standard error (records))",
        ["preset", "twin", "mean", "sd", "largest", "within 5 %", "covers", "vs as is"],
        summary,
    )


def answer(name: str, what: str, mult: float, seed: int, noise: int | None, over: dict[str, object]) -> dict[str, Any]:
    """``identify`` on one record of the twin with ``over``: gap, fit over the floor, inertia ratio, the play in the
    output encoder's counts, the interval over the truth, seconds."""
    rec = twin_record(name, mult, 1.0, "sines", seed, noise, **over)
    result, seconds = run(rec["u"], rec["y"], rec["period"])  # type: ignore[arg-type]
    truth = float(rec["play"])  # type: ignore[arg-type]
    fit = float(result.loop.fit_nrmse) if result.loop is not None else result.fit_nrmse
    mu = result.loop.model.mu if result.loop is not None and result.loop.model.massive else 0.0
    lo, hi = result.play_interval
    cpr = float(over.get("load_encoder_cpr", 4096))  # type: ignore[arg-type]
    return {
        "preset": name, "effect": what, "mult": mult, "seed": seed, "noise_seed": noise, "structure": result.structure,
        "gap": result.play / truth - 1.0, "fit": fit / float(rec["floor"]), "mu": float(mu),  # type: ignore[arg-type]
        "counts": truth * cpr / (2.0 * np.pi), "lo": lo / truth if np.isfinite(lo) else None,
        "hi": hi / truth if np.isfinite(hi) else None, "covers": bool(np.isfinite(lo) and lo <= truth <= hi),
        "identifiable": bool(result.identifiable), "s": seconds,
    }  # fmt: skip


if __name__ == "__main__":
    main()
