"""Which of a twin's effects carries identify's play error (issue 12): one effect switched off at a time.

Run: ``.venv/bin/python benchmarks/twin_effects.py --presets odrive --rates 20,50 --seeds 1,2
[--effects "as is,gear x100 stiffer"] [--fine]``.

Each row is :func:`servoid.ident.identify` as ``real_servos.py`` runs it (no structure flags) on
the same gentle-sines record (``real_servos.twin_record``: same excitation seed, same noise seed)
from the twin with one of its effects switched off or scaled: the gear contact (compliance,
damping, losses), the load (inertia, friction), the motor's friction (its break-away hump, all
of it), the drive (its velocity estimate: filter or encoder PLL; its current loop; its loop
rate; the loop encoder's resolution) and the output encoder (``--fine`` reads every record with
a 2**20-count output encoder and no noise, so that the model's own error shows above the floor).
``--duration-s`` runs each record longer (or shorter) than the table's 40 s. ``--noise-seeds``
draws the encoders' noise from each of those seeds on every record (the same excitation): the spread of the answers over them is what the record's resolution and noise
alone leave, which no model can remove. The last table gives each effect's play errors over the records and their mean and mean
absolute value: an effect that carries the error moves all records towards 0, not one.
The twins' physics and presets are not changed (only this run's copies, through the preset's
overrides). The machine may be shared: times are one run each.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import real_servos
from _table import table
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
        "loop encoder x64 counts": {"motor_encoder_cpr": 64 * b.motor_encoder_cpr},
    }  # fmt: skip
    if b.pll_bandwidth_rad_s > 0:
        cases["PLL x2 faster"] = {"pll_bandwidth_rad_s": 2 * b.pll_bandwidth_rad_s}
        cases["PLL x2 faster, loop encoder x64"] = {"pll_bandwidth_rad_s": 2 * b.pll_bandwidth_rad_s, "motor_encoder_cpr": 64 * b.motor_encoder_cpr}  # fmt: skip
    if b.velocity_filter_s > 0:
        cases["velocity filter off"] = {"velocity_filter_s": 0.0}
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
        help="comma-separated seeds of the encoders' noise, each on every record (default: the record's seed)",
    )
    parser.add_argument(
        "--duration-s",
        type=float,
        default=real_servos.DURATION_S,
        help="the record's length, s (default: the table's; the table's sample cap scaled with it)",
    )
    args = parser.parse_args()
    # a longer record: the table's excitation run on for longer, its sample cap scaled alike
    real_servos.MAX_SAMPLES = round(real_servos.MAX_SAMPLES * args.duration_s / real_servos.DURATION_S)
    real_servos.DURATION_S = args.duration_s
    noise_seeds: list[int | None] = [int(s) for s in args.noise_seeds.split(",") if s.strip()] or [None]
    fine: dict[str, object] = {"load_encoder_cpr": 2**20, "encoder_noise_counts": 0.0} if args.fine else {}
    rows: list[list[str]] = []
    gaps: dict[tuple[str, str], list[float]] = {}
    for name in args.presets.split(","):
        cases = effects(name)
        wanted = [e.strip() for e in args.effects.split(",") if e.strip()] or list(cases)
        for what in wanted:
            if what not in cases:
                raise SystemExit(f"effect (={what!r}) must be one of {', '.join(cases)}")
            for mult in (float(r) for r in args.rates.split(",")):
                for seed, noise in ((int(s), n) for s in args.seeds.split(",") for n in noise_seeds):
                    rec = twin_record(name, mult, 1.0, "sines", seed, noise, **{**cases[what], **fine})
                    t0 = time.perf_counter()
                    result, _ = run(rec["u"], rec["y"], rec["period"])  # type: ignore[arg-type]
                    gap = result.play / float(rec["play"]) - 1.0  # type: ignore[arg-type]
                    gaps.setdefault((name, what), []).append(gap)
                    fit = float(result.loop.fit_nrmse) if result.loop is not None else result.fit_nrmse
                    mu = result.loop.model.mu if result.loop is not None and result.loop.model.massive else 0.0
                    rows.append([
                        name, what, f"{mult:g}x", str(seed) if noise is None else f"{seed}/{noise}", result.structure, f"{gap:+.1%}",
                        f"{fit / float(rec['floor']):.2f}", f"{mu:.2f}", f"{time.perf_counter() - t0:.1f}",
                    ])  # fmt: skip
                    print(" | ".join(rows[-1]), flush=True)
    enc = "2**20-count output encoder, no noise" if args.fine else "4096 counts, 0.3 count noise"
    table(f"identify on each record, one effect switched off ({enc})", ["preset", "twin", "rate", "seed(/noise)", "structure", "gap", "fit/floor", "mu", "s"], rows)  # fmt: skip
    summary = [
        [name, what, ", ".join(f"{g:+.1%}" for g in v), f"{np.mean(v):+.1%}", f"{np.mean(np.abs(v)):.1%}", str(sum(abs(g) <= 0.05 for g in v))]
        for (name, what), v in gaps.items()
    ]  # fmt: skip
    table("Per effect over the records", ["preset", "twin", "gaps", "mean", "mean |gap|", "within 5 %"], summary)


if __name__ == "__main__":
    main()
