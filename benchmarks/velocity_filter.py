"""Does the model's velocity filter lag as the drive's does? A cascade twin's step against the model over ``tv``.

Run: ``.venv/bin/python benchmarks/velocity_filter.py [--preset cia402] [--tvs-ms 0,0.25,0.5,0.75,1,1.25,1.5,2]``.

The twin (a cascade preset: position P over velocity PI over a current loop, ticks of its control rate) without
play and friction, its load always in contact, takes a small position step; its motor side (``theta_m / N``) at
samples of two control ticks is compared with :class:`~servoid.ident.models.servo_loop.ServoLoopModel` at the twin's
own rates per the pair's inertia (``kp``, ``kv = Kp_vel Kt / J``, ``ki = Ki_vel Kt / J``) for each model ``tv``, with
the twin's velocity filter as the preset has it and switched off. The rms error is a share of the step. The model has
no ticks, current loop or gear compliance: its error at its best ``tv`` is what those leave.
"""

from __future__ import annotations

import argparse

import numpy as np
from _table import table

from servoid.drivers.twin import Twin, preset
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import OUTPUT_BACKLASH

#: The step, output rad, and the samples before and after it.
STEP_RAD = 0.002
BEFORE, SAMPLES = 5, 100
#: What is switched off on the twin: the play (to a tenth of a microradian) and every friction.
QUIET = {
    "play_rad": 1e-7,
    "encoder_noise_counts": 0.0,
    "motor_coulomb_nm": 0.0,
    "motor_breakaway_nm": 0.0,
    "motor_viscous_nms": 0.0,
    "load_coulomb_nm": 0.0,
    "load_breakaway_nm": 0.0,
    "load_viscous_nms": 0.0,
}


def errors(name: str, twin_tv: float, tvs: list[float]) -> list[float]:
    """The rms error (a share of the step) of the model at each of ``tvs`` against the twin with its filter at ``twin_tv``."""
    base = preset(name)
    if base.firmware != "cascade":
        raise SystemExit(f"preset (={name!r}) must run the cascade firmware (it has {base.firmware!r})")
    inertia = base.motor_inertia_kgm2 + base.load_inertia_kgm2 / base.gear_ratio**2
    kv = base.vel_kp_a_rad_s * base.torque_constant_nm_a / inertia
    ki = base.vel_ki_a_rad * base.torque_constant_nm_a / inertia
    period = 2.0 / base.control_rate_hz
    u = np.r_[np.zeros(BEFORE), np.full(SAMPLES - BEFORE, STEP_RAD)]
    twin = Twin(preset(name, **QUIET, velocity_filter_s=twin_tv), seed=1)
    twin.enable()
    x = np.asarray(twin.sample(u, period).true_gear_side_rad)
    x = x - x[0]
    out = []
    for tv in tvs:
        model = ServoLoopModel(OUTPUT_BACKLASH, period, kp=base.pos_kv_1_s, kv=kv, ki=ki, veps=1e-6, tv=tv)
        out.append(float(np.sqrt(np.mean((x - model.simulate(u, y0=0.0)) ** 2)) / STEP_RAD))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="cia402")
    parser.add_argument("--tvs-ms", default="0,0.25,0.5,0.75,1,1.25,1.5,2")
    args = parser.parse_args()
    tvs = [1e-3 * float(v) for v in args.tvs_ms.split(",")]
    own = preset(args.preset).velocity_filter_s
    rows = []
    for twin_tv in dict.fromkeys((own, 0.0)):
        errs = errors(args.preset, twin_tv, tvs)
        best = tvs[int(np.argmin(errs))]
        rows.append([f"{1000 * twin_tv:g}", *(f"{100 * e:.2f} %" for e in errs), f"{1000 * best:g}"])
    table(
        f"{args.preset}: the twin's motor after a {1000 * STEP_RAD:g} mrad step against the model (rms, share of the step)",
        ["twin's filter (ms)", *(f"model tv {1000 * tv:g} ms" for tv in tvs), "best tv (ms)"],
        rows,
    )


if __name__ == "__main__":
    main()
