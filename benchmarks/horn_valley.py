"""The horn stage's valley over the play: which of its parameters move along it (issues 15 and 12, hornprof22).

Run: ``.venv/bin/python benchmarks/horn_valley.py [--offline-seeds 0 1] [--preset sts3215] [--seconds 40]
[--ends 25 30 35 40] [--runs DIR ...] [--back-ends 15 10 5 0] [--grid 0.8 ... 1.2] [--hold al wc zeta]``.

On each record end (offline: ``--seconds`` of gentle sines of the ``--preset`` twin at 200 Hz, peak accelerations
up to ``--accel``, as ``horn_live.py`` draws them, cut at ``--ends`` s; live: the runs ``online.py --keep DIR`` kept,
cut ``--back-ends`` s before their end, as ``horn_profile.py --back`` cuts them) the massless search
(``fit_loop``) and the horn stage (``with_horn``), as identification runs them. Where the horn stage keeps a horn,
the profile over the play of *that horn's* model: the play held at ``--grid`` times the twin's true play, every
other parameter of the stage refitted on every kept sample (from the answer and from the neighbouring point's fit,
the lower cost kept, as ``horn_profile.py``). Printed per point: the cost above the answer's in the answer's
residual variances (``(cost - cost_answer) / (cost_answer / n)``; a profile that rises by a few of them only is a
cost that cannot tell the plays apart) and the refitted parameters: the horn's friction ``al`` (rad/s^2), the
contact's ``wc`` (rad/s) and ``zeta``, the loop's ``kp``, ``kv``, the motor's Coulomb ``fc`` and break-away ``fs``
and the stall band ``max(fs, fc) / (kp kv)`` (the set-point error the loop needs to move the motor, as a share of
the play held), and ``coast``: the distance the horn coasts, ``v^2 / (2 al)``, from the record's typical speed
``v`` (the set point's rms speed): the two lengths besides the play that hold the horn where the play would.
``--twin NAME=VALUE ...``: the offline twin's preset with those overridden (a diagnosis of which of the twin's terms
moves the valley; the truth is the overridden preset's); ``--read-cpr N``: its record re-read at N counts per
revolution (``real_servos.coarse_reading``: a loop on finer counts, the readings as coarse as N). ``--count-loss`` (offline records; a prototype): every fit's residual taken outside the reading's count (the
position within half the record's smallest step of the reading costs nothing). ``--force``: where the stage keeps no horn (no rebound named, or the horn not validating better), the stage run
past those two gates, and its horn profiled (marked "forced"). ``--hold NAMES``: each profile again with those names held at the answer's values (not refitted): how much of the
valley's flatness their freedom makes. The twin's own horn (``al``, ``wc``, ``zeta`` and the inertia ratio
computed from the preset) is printed once per preset, for reference: never used by the fits.

The machine may be shared: the load is printed.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from servoid.drivers.twin import Twin, preset
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import horn_contact as hc
from servoid.ident.offline import loop_fit as lf

RATE = 200.0
AMPLITUDE = 0.1
#: The refitted values printed per profile point (the fit's own names).
SHOWN = ("al", "wc", "zeta", "kp", "kv", "fc", "fs")


def twin_horn(name: str) -> str:
    """The twin's own horn in the model's terms, from its preset (for reference only)."""
    p = preset(name)
    n = p.gear_ratio
    mu = p.load_inertia_kgm2 / (p.motor_inertia_kgm2 * n * n)
    al = p.load_coulomb_nm / p.load_inertia_kgm2
    als = p.load_breakaway_nm / p.load_inertia_kgm2
    wc = math.sqrt(p.gear_stiffness_nm_rad / p.load_inertia_kgm2)
    zeta = p.gear_damping_nms / (2.0 * math.sqrt(p.gear_stiffness_nm_rad * p.load_inertia_kgm2))
    return (f"{name} twin: play {p.play_rad:.5f} rad, load mu {mu:.3f}, friction al {al:.1f} (break-away {als:.1f}) "
            f"rad/s^2, contact wc {wc:.0f} rad/s, zeta {zeta:.3f} on the load alone")  # fmt: skip


def offline_record(
    name: str, accel: float, seconds: float, seed: int, overrides: dict[str, str] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The ``name`` twin (its preset with ``overrides``) driven by gentle sines up to ``accel`` rad/s^2 for
    ``seconds`` at :data:`RATE` (``horn_live.py``'s record, any preset)."""
    twin = Twin(preset(name, **(overrides or {})), seed=seed)
    twin.enable()
    spec = GentleSpec(amplitude=AMPLITUDE, accel=accel / RATE**2, spread=8.0)
    rec = twin.sample(sample(spec, int(seconds * RATE), seed=seed + 1000), 1.0 / RATE)
    return np.asarray(rec.u, dtype=np.float64), np.asarray(rec.y, dtype=np.float64)


def _row(d: dict[str, float], play: float, v_typ: float) -> str:
    stall = max(d["fs"], d["fc"]) / (d["kp"] * d["kv"])
    coast = v_typ * v_typ / (2.0 * d["al"]) if d.get("al", 0.0) > 0.0 else math.nan
    vals = " ".join(f"{k} {d[k]:.4g}" for k in SHOWN if k in d)
    return f"{vals} stall {stall / play:.2f}p coast {coast / play:.2f}p"


def _forced(u: np.ndarray, y: np.ndarray, period: float, whole: lf.LoopChoice, kept: np.ndarray) -> lf.LoopChoice:
    """The horn stage run past its two gates (the rebound named, the horn validating better): a benchmark's look at
    the horn model's valley where identification would not keep it (``--force``)."""
    named, margin = hc.rebound, lf.LOAD_MARGIN

    class _Named:
        named = True

    hc.rebound = lambda *a, **k: _Named()
    lf.LOAD_MARGIN = -1e9
    try:
        return hc.with_horn(u, y, period, whole, kept)
    finally:
        hc.rebound, lf.LOAD_MARGIN = named, margin


def count_loss(y: np.ndarray) -> None:
    """Every fit's residual read as a count's reading (``--count-loss``, a prototype): a reading ``y`` says the
    position lies within half a count of it, so the residual is the model's distance outside that interval,
    ``sign(r) max(|r| - q / 2, 0)``, with ``q`` the record's own smallest step between readings (as the probe
    reads the quantisation). Patches ``loop_fit._Problem.scored`` for the rest of the process."""
    steps = np.abs(np.diff(y[np.isfinite(y)]))
    half = 0.5 * float(np.min(steps[steps > 0.0]))
    scored = lf._Problem.scored
    base = getattr(scored, "__wrapped__", scored)

    def counted(self: Any, y_hat: np.ndarray) -> np.ndarray:
        r: np.ndarray = base(self, y_hat)
        out: np.ndarray = np.sign(r) * np.maximum(np.abs(r) - half, 0.0)
        return out

    counted.__wrapped__ = base  # type: ignore[attr-defined]
    lf._Problem.scored = counted


def valley(
    u: np.ndarray, y: np.ndarray, kept: np.ndarray, period: float, truth: float, grid: list[float],
    load: bool | None, holds: list[tuple[str, ...]], force: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """Print the answers and the horn model's profile (its refitted values per point) on one record."""
    t0 = time.perf_counter()
    whole = lf.fit_loop(u, y, period, keep=kept, load=load)
    found = hc.with_horn(u, y, period, whole, kept)
    forced = False
    if force and not (found is not whole and found.model.compliant) and whole.structure == PLAY_IN_LOOP:
        found, forced = _forced(u, y, period, whole, kept), True
    kept_horn = found is not whole and found.model.compliant
    said = ("forced" if forced else "kept") if kept_horn else "not kept"
    print(f"  massless {whole.structure} {whole.play / truth - 1:+.1%}; horn "
          f"{said}{f' {found.play / truth - 1:+.1%}' if kept_horn else ''} [{time.perf_counter() - t0:.0f} s]")  # fmt: skip
    out: dict[str, Any] = {"massless": whole.play / truth, "horn": found.play / truth if kept_horn else None}
    if not kept_horn:
        return out
    centre = float(np.mean(u))
    uc, yc = np.ascontiguousarray(u - centre), np.ascontiguousarray(y - centre)
    _, kv = lf._linear_start(uc, yc, period)
    a_scale = 0.1 * kv * float(np.std(np.diff(yc))) / period
    v_typ = float(np.sqrt(np.mean(np.diff(u) ** 2))) / period
    n = int(np.count_nonzero(kept))
    model = found.model
    d = hc._values(model)
    base = lf._cost(uc, yc, period, PLAY_IN_LOOP, d, kept)
    print(f"    answer {model.play / truth:.3f}x: {_row(d, model.play, v_typ)}")
    free_all = lf._free(PLAY_IN_LOOP, model.ki > 0.0) + hc.HORN
    for held in [(), *holds]:
        free = tuple(f for f in free_all if f not in held)
        t1 = time.perf_counter()
        order = sorted(grid, key=lambda g: abs(g * truth - model.play))
        fits: dict[float, tuple[dict[str, float], float]] = {}
        for g in order:
            near = min(fits, key=lambda h: abs(h - g), default=None)
            best = hc.held_play_fit(uc, yc, period, d, g * truth, kept, a_scale, model.ki > 0.0, free,
                                    max_nfev=lf.FINAL_NFEV + lf.CANDIDATE_NFEV)[:2]  # fmt: skip
            if near is not None:
                other = hc.held_play_fit(uc, yc, period, fits[near][0], g * truth, kept, a_scale, model.ki > 0.0,
                                         free, max_nfev=lf.FINAL_NFEV + lf.CANDIDATE_NFEV)[:2]  # fmt: skip
                best = min(best, other, key=lambda f: f[1])
            fits[g] = best
        label = f"held {'/'.join(held)}" if held else "all refitted"
        print(f"    profile, {label} [{time.perf_counter() - t1:.0f} s]:")
        for g in sorted(fits):
            fd, cost = fits[g]
            print(f"      {g:.2f}x {(cost - base) / (base / n):+8.1f} var  {_row(fd, g * truth, v_typ)}")
        out[label] = {g: ((fits[g][1] - base) / (base / n), fits[g][0]) for g in fits}
    sys.stdout.flush()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="sts3215", help="the offline records' twin")
    parser.add_argument("--offline-seeds", type=int, nargs="*", default=[])
    parser.add_argument("--accel", type=float, default=8.0, help="the gentle sines' peak acceleration, rad/s^2")
    parser.add_argument("--seconds", type=float, default=40.0, help="the offline record's length, s")
    parser.add_argument("--ends", type=float, nargs="+", default=[25.0, 30.0, 35.0, 40.0], help="offline ends, s")
    parser.add_argument("--runs", type=Path, nargs="*", default=[], help="online.py --keep run directories")
    parser.add_argument("--back-ends", type=float, nargs="+", default=[15.0, 10.0, 5.0, 0.0])
    parser.add_argument("--grid", type=float, nargs="*",
                        default=[0.8, 0.85, 0.9, 0.95, 1.0, 1.05, 1.1, 1.15, 1.2], help="plays / truth")  # fmt: skip
    parser.add_argument("--hold", nargs="*", action="append", default=[], help="names held in a second profile")
    parser.add_argument("--twin", nargs="*", default=[], metavar="NAME=VALUE",
                        help="the offline twin's preset overridden (a diagnosis: which of its terms moves the valley)")  # fmt: skip
    parser.add_argument("--read-cpr", type=int, default=0,
                        help="the offline record re-read at these counts per revolution (a --twin finer encoder's loop, "
                        "the readings as coarse as this)")  # fmt: skip
    parser.add_argument("--count-loss", action="store_true", help="every fit's residual outside the reading's count")
    parser.add_argument("--force", action="store_true", help="the horn stage past its gates where it keeps no horn")
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    holds = [tuple(h) for h in args.hold if h]
    print(f"machine load (1 min): {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores", flush=True)
    for name in sorted({args.preset, *(r.name.split("-")[0] for r in args.runs)}):
        print(twin_horn(name))
    overrides = dict(kv.split("=", 1) for kv in args.twin)
    if overrides:
        print(f"the offline twin's preset overridden: {overrides}")
    truth = preset(args.preset, **overrides).play_rad
    for seed in args.offline_seeds:
        u, y = offline_record(args.preset, args.accel, args.seconds, seed, overrides)
        if args.read_cpr:
            from real_servos import coarse_reading

            fine = int(preset(args.preset, **overrides).load_encoder_cpr)
            y = coarse_reading(y, fine, fine // args.read_cpr)
        if args.count_loss:
            count_loss(y)
        for end in args.ends:
            m = int(round(end * RATE))
            print(f"{args.preset} gentle sines {args.accel:g} rad/s^2 seed {seed} to {end:g} s ({m} samples):")
            valley(u[:m], y[:m], np.ones(m, dtype=bool), 1.0 / RATE, truth, args.grid, None, holds, args.force)
    if args.runs:
        from horn_profile import live_ends

        for _, _, (u, y, kept, period, name) in live_ends(args.runs, args.back_ends, back=True):
            valley(u, y, kept, period, preset(name).play_rad, args.grid, False, holds, args.force)
    print(f"machine load (1 min) at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
