"""Confident wrong answers on servos the table does not hold (issue 12): each preset with one physical parameter changed.

Run: ``.venv/bin/python benchmarks/variants.py`` (the default subset, 20x, seeds 3 and 4, ~15-30 min);
``--full`` (rates 10, 20 and 50x); ``--presets sts3215 --variants damp*10 --rates 10 --seeds 3`` for one cell.

Every row is ``identify`` with no structure flags (:func:`real_servos.run`) on a twin record
(:func:`real_servos.twin_record`: gentle sines, 4096-count output encoder, 0.3 count of noise)
whose preset has ONE physical parameter moved within what real servos of its kind have:
the load's inertia x0.3 and x3, the gears' stiffness x0.3 and x3 and damping x0.3 and x10,
the motor's friction x0.3 and x4, the encoders' noise 0 and 1 count, a 1024- or 16384-count
output encoder, the play x0.5 and x3, the position gain x0.5 and x2 and, where the drive has
one, the velocity loop's gains (both, or the Feetech's D term) x0.5 and x2. The rates are
multiples of the NOMINAL preset's loop bandwidth (:data:`real_servos.BANDWIDTH_HZ`): a variant
with other gains is sampled at the same rate. Seeds 3 and 4 (the table's are 1 and 2).

Columns: the variant, the gap error against the variant's true play, whether the verdict said
identifiable, whether the 95 % interval covers the truth, the place named (the true place:
"named" when the verdict names the true place, "undetermined" when it withholds it, "WRONG"
when it names the other), the answering model's fit against the record's floor, the failed
rules, the seconds. Last, the counts: identifiable and wrong (the other place, |gap| beyond the
issue's target for the true place, 5 % motor side and 15 % in the loop, or an interval that
excludes the truth), withheld right and wrong, coverage of the reported intervals.
"""

from __future__ import annotations

import argparse
import fnmatch

import numpy as np
from _table import table
from real_servos import BANDWIDTH_HZ, answer_fit, reasons, right, run, twin_record

from servoid.drivers.twin import preset

#: One physical parameter each: name -> (the twin fields it scales, factor). ``frictions`` goes through
#: twin_record's own friction factor; ``noise`` and ``cpr`` set values, not factors.
SCALED = {
    "load": ("load_inertia_kgm2",),
    "stiff": ("gear_stiffness_nm_rad",),
    "damp": ("gear_damping_nms",),
    "play": ("play_rad",),
}
FACTORS = {"load": (0.3, 3.0), "stiff": (0.3, 3.0), "damp": (0.3, 10.0), "play": (0.5, 3.0), "fric": (0.3, 4.0),
           "pos": (0.5, 2.0), "vel": (0.5, 2.0)}  # fmt: skip
#: The position gain and the velocity loop's gains by firmware (the Dynamixel's D term is 0 in the preset: no vel).
GAINS = {
    "cascade": {"pos": ("pos_kv_1_s",), "vel": ("vel_kp_a_rad_s", "vel_ki_a_rad")},
    "dynamixel_position": {"pos": ("pos_p",)},
    "feetech_position": {"pos": ("pos_p",), "vel": ("pos_d",)},
}
NOISES_COUNTS = (0.0, 1.0)
CPRS = (1024, 16384)


def variants(name: str) -> list[tuple[str, float, dict[str, object]]]:
    """A preset's variants: (label, friction factor, twin overrides)."""
    base = preset(name)
    out: list[tuple[str, float, dict[str, object]]] = []
    fields = dict(SCALED, **GAINS[base.firmware])
    for key, names in fields.items():
        for f in FACTORS[key]:
            out.append((f"{key}*{f:g}", 1.0, {n: f * float(getattr(base, n)) for n in names}))
    out += [(f"fric*{f:g}", f, {}) for f in FACTORS["fric"]]
    out += [(f"noise={s:g}", 1.0, {"encoder_noise_counts": s}) for s in NOISES_COUNTS]
    out += [(f"cpr={c}", 1.0, {"load_encoder_cpr": c}) for c in CPRS]
    return out


def sweep(presets: list[str], rates: list[float], seeds: list[int], patterns: list[str]) -> None:
    cols = ["preset", "variant", "rate", "seed", "gap", "identifiable", "covers", "place", "fit/floor", "verdict", "s"]
    rows: list[list[str]] = []
    confusion: dict[str, list[str]] = {}
    covered = reported = 0
    for name in presets:
        for label, friction, over in variants(name):
            if not any(fnmatch.fnmatch(label, p) for p in patterns):
                continue
            for mult in rates:
                for seed in seeds:
                    rec = twin_record(name, mult, friction, "sines", seed, **over)
                    try:
                        result, seconds = run(rec["u"], rec["y"], rec["period"])  # type: ignore[arg-type]
                    except Exception as exc:  # noqa: BLE001 - a benchmark prints what happened and goes on
                        rows.append([name, label, f"{mult:g}x", str(seed), f"error: {exc}"[:60], *[""] * 6])
                        print(" | ".join(rows[-1]), flush=True)
                        continue
                    play = float(rec["play"])  # type: ignore[arg-type]
                    lo, hi = result.play_interval
                    covers = bool(np.isfinite(lo) and lo <= play <= hi)
                    reported += bool(np.isfinite(lo))
                    covered += covers
                    if result.verdict.structure_undetermined:
                        place = "undetermined"
                    else:
                        place = "named" if result.structure == rec["structure"] else "WRONG"
                    wrong = not right(rec, result, "sines") or (np.isfinite(lo) and not covers)
                    cell = ("identifiable" if result.identifiable else "withheld") + (" WRONG" if wrong else " right")
                    tag = f"{name} {label} {mult:g}x s{seed}"
                    confusion.setdefault(cell, []).append(
                        tag if result.identifiable else f"{tag} ({reasons(result)[5:]})"
                    )
                    rows.append([
                        name, label, f"{mult:g}x", str(seed), f"{100 * (result.play / play - 1):+.1f} %",
                        "yes" if result.identifiable else "no",
                        "yes" if covers else ("none" if not np.isfinite(lo) else "no"), place,
                        f"{answer_fit(result) / float(rec['floor']):.2f}",  # type: ignore[arg-type]
                        reasons(result), f"{seconds:.1f}",
                    ])  # fmt: skip
                    print(" | ".join(rows[-1]), flush=True)
    table("Variants: identify with no structure flags on a preset with one parameter changed "
          "(gap = play / true play - 1)", cols, rows)  # fmt: skip
    print(f"intervals covering the true play: {covered} of {reported} reported ({len(rows)} runs)")
    print("right = the true place and |gap| within the target (5 % motor side, 15 % in the loop) and,")
    print("when there is an interval, the interval covering the truth")
    for cell in ("identifiable WRONG", "identifiable right", "withheld WRONG", "withheld right"):
        runs = confusion.get(cell, [])
        listed = runs if cell.startswith("identifiable") else []
        print(f"  {cell}: {len(runs)}" + "".join(f"\n    {r}" for r in listed))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="rates 10, 20 and 50x (default 20x)")
    ap.add_argument("--presets", default=",".join(BANDWIDTH_HZ), help="comma-separated presets (default: all)")
    ap.add_argument("--rates", help="comma-separated rates, multiples of the nominal loop bandwidth")
    ap.add_argument("--seeds", default="3,4", help="comma-separated seeds (default 3,4)")
    ap.add_argument("--variants", default="*", help="comma-separated label patterns, e.g. 'damp*,play*3'")
    args = ap.parse_args()
    rates = [float(r) for r in args.rates.split(",")] if args.rates else ([10.0, 20.0, 50.0] if args.full else [20.0])
    sweep(args.presets.split(","), rates, [int(s) for s in args.seeds.split(",")], args.variants.split(","))


if __name__ == "__main__":
    main()
