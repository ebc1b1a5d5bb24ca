"""What decides the play-in-loop answer on the horn twins: the twins' effects switched off one at a time.

Run: ``.venv/bin/python benchmarks/horn_effects.py [--presets xm430,sts3215] [--kinds steps]
[--rates 20] [--seeds 1] [--variants base,motor_friction_0]``.

The records are ``real_servos.py``'s (the same twins, excitations, noise and
seeds), with some of the twin's parameters overridden through its options (the
presets are not edited). Two tables:

1. **How much the play shows in the record.** The twin run twice with the same
   seed (the same set points, the same noise), once with its play and once with
   none (and once with twice the play), and the RMS of the difference between
   the two recorded outputs over the record's floor (quantisation and noise,
   ``q sqrt(1/12 + 0.3^2)``, as in ``real_servos.py``). About 1 or less: the
   recorded output hardly depends on the play, and no model can tell the play
   from the noise. Also with the motor's friction switched off, and with the
   drive's loop closed on a motor encoder instead (:func:`motor_loop`: the play
   outside the loop, the same gain), for scale.
2. **The servo-loop fit with one effect switched off** (``fit_loop``, both
   places of the play, with no structure flags): the place it chose and its
   margin, the play against the twin's, and how both places validate against
   the floor. The row whose change brings the answer to the true place and
   play names the effect the model misses.

Printed as measured; one run each (the machine may be shared).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from _table import table
from real_servos import NOISE_COUNTS, twin_record

from servoid.drivers.twin import preset
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
from servoid.ident.offline.loop_fit import fit_loop

VISIBILITY_COLUMNS = ["preset", "excitation", "rate", "seed", "play -> 0", "play -> 2x", "no motor friction: -> 0",
                      "-> 2x", "loop on the motor: -> 0"]  # fmt: skip


def variants(name: str) -> dict[str, dict[str, object]]:
    """The effects switched off (or changed), by label: twin parameter overrides."""
    p = preset(name)
    out: dict[str, dict[str, object]] = {
        "base": {},
        "load_inertia_x0.01": {"load_inertia_kgm2": 0.01 * p.load_inertia_kgm2},
        "load_friction_x20": {"load_coulomb_nm": 20.0 * p.load_coulomb_nm, "load_breakaway_nm": 20.0 * p.load_breakaway_nm},
        "gear_stiffness_x100": {"gear_stiffness_nm_rad": 100.0 * p.gear_stiffness_nm_rad},
        "gear_damping_x10": {"gear_damping_nms": 10.0 * p.gear_damping_nms},
        "breakaway_=_coulomb": {"motor_breakaway_nm": p.motor_coulomb_nm},
        "motor_friction_0": {"motor_coulomb_nm": 0.0, "motor_breakaway_nm": 0.0},
        "encoder_noise_0": {"encoder_noise_counts": 0.0},
    }  # fmt: skip
    if p.pos_d > 0.0:
        out["pos_d_0"] = {"pos_d": 0.0}
        out["pos_d_0_motor_friction_0"] = {"pos_d": 0.0, "motor_coulomb_nm": 0.0, "motor_breakaway_nm": 0.0}
    if p.deadband_counts > 0.0 or p.min_output > 0.0:
        out["deadband_min_output_0"] = {"deadband_counts": 0.0, "min_output": 0.0}
    return out


def _floor(rec: dict[str, object]) -> float:
    """The record's floor in its own unit (``real_servos``' NRMSE floor times the output's spread)."""
    return float(rec["floor"]) * float(np.std(np.asarray(rec["y"])))  # type: ignore[arg-type]


def motor_loop(name: str) -> dict[str, object]:
    """The same drive with its loop closed on a motor encoder instead of the horn's (the play outside the loop).

    The PID firmware works in counts of its loop encoder: a motor encoder of ``round(4096 / N)`` counts
    per motor turn, with the gains scaled so that the loop's gain per output radian stays the horn
    loop's (the rounding leaves it within a few per cent, the encoder's resolution at the output too).
    """
    p = preset(name)
    cpr = max(1, round(4096 / p.gear_ratio))
    scale = cpr * p.gear_ratio / 4096
    return {"loop_encoder": "motor", "motor_encoder_cpr": cpr, "pos_p": p.pos_p / scale, "pos_d": p.pos_d / scale}


def visibility(name: str, mult: float, kind: str, seed: int) -> list[str]:
    """RMS of the recorded output's change when the play goes to 0 (and to twice), over the floor."""
    play = preset(name).play_rad
    cells = []
    for extra in ({}, {"motor_coulomb_nm": 0.0, "motor_breakaway_nm": 0.0}, motor_loop(name)):
        with_play = twin_record(name, mult, 1.0, kind, seed, **extra)
        floor = _floor(with_play)
        y = np.asarray(with_play["y"])
        for other in (1e-9, 2.0 * play):
            y2 = np.asarray(twin_record(name, mult, 1.0, kind, seed, play_rad=other, **extra)["y"])
            cells.append(f"{float(np.sqrt(np.mean((y - y2) ** 2))) / floor:.2f}")
        if "loop_encoder" in extra:
            cells = cells[:-1]  # the motor loop: the play's change only
    return [name, kind, f"{mult:g}x", str(seed), *cells]


def effect_row(name: str, mult: float, kind: str, seed: int, label: str, over: dict[str, object]) -> list[str]:
    """``fit_loop`` on the record with ``over`` applied: its choice, margin, play and validations."""
    rec = twin_record(name, mult, 1.0, kind, seed, **over)
    floor = float(rec["floor"])  # type: ignore[arg-type]
    started = time.perf_counter()
    choice = fit_loop(rec["u"], rec["y"], float(rec["period"]))  # type: ignore[arg-type]
    seconds = time.perf_counter() - started
    inside = min((c for c in choice.candidates if c.structure == PLAY_IN_LOOP), key=lambda c: c.validation_nrmse)
    truth = float(rec["play"])  # type: ignore[arg-type]
    return [
        name, kind, f"{mult:g}x", str(seed), label, choice.structure, f"{100 * choice.margin:.1f} %",
        f"{100 * (choice.play / truth - 1):+.1f} %", f"{100 * (inside.model.play / truth - 1):+.1f} %",
        f"{choice.validation_nrmse[OUTPUT_BACKLASH] / floor:.2f}", f"{choice.validation_nrmse[PLAY_IN_LOOP] / floor:.2f}",
        f"{seconds:.1f}",
    ]  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="xm430,sts3215", help="comma-separated horn presets")
    ap.add_argument("--kinds", default="steps", help="comma-separated excitations: steps (held), sines (gentle)")
    ap.add_argument("--rates", default="20", help="comma-separated rates, multiples of the loop bandwidth")
    ap.add_argument("--seeds", default="1", help="comma-separated twin seeds")
    ap.add_argument("--variants", help="comma-separated effect labels (default: all of the preset's)")
    ap.add_argument("--no-fits", action="store_true", help="only the first table (no fits)")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    grid = [
        (name, float(mult), kind, int(seed))
        for name in args.presets.split(",")
        for kind in args.kinds.split(",")
        for mult in args.rates.split(",")
        for seed in args.seeds.split(",")
    ]
    rows = [visibility(*g) for g in grid]
    table(
        f"How much the play shows: RMS of the recorded output's change over the floor (noise {NOISE_COUNTS} count)",
        VISIBILITY_COLUMNS,
        rows,
    )
    if args.no_fits:
        return
    fits = []
    for name, mult, kind, seed in grid:
        chosen = variants(name)
        labels = args.variants.split(",") if args.variants else list(chosen)
        for label in labels:
            if label not in chosen:
                continue
            fits.append(effect_row(name, mult, kind, seed, label, chosen[label]))
            print(" | ".join(fits[-1]), flush=True)
    table(
        "fit_loop with one effect switched off (gap = play / the twin's play - 1; validation over the floor)",
        ["preset", "excitation", "rate", "seed", "twin changed", "choice", "margin", "gap", "in-loop cand. gap",
         "val motor side", "val in loop", "s"],
        fits,
    )  # fmt: skip


if __name__ == "__main__":
    main()
