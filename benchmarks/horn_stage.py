"""A light horn that rebounds off the flanks: what the servo-loop model's massive load does to the play in the loop.

Run: ``.venv/bin/python benchmarks/horn_stage.py [--records sts3215:20:1,xm430:20:1] [--own]``.

An experiment, not a feature: the default fit has a massless load, and the load
stage of :mod:`servoid.ident.offline.load_stage` only tries heavy loads (inertia
ratios 0.3-3 behind a play outside the loop). The horn of a Dynamixel or Feetech
servo is light against the motor seen through its gear (the twins: 0.026) and
rebounds off the flank the motor hits (the twins' gear contact damps to a
restitution of about 0.78), so it floats inside the play for part of each
reversal and the massless model books that as less play. Here, on the best
play-in-loop candidate of :func:`~servoid.ident.offline.loop_fit.fit_loop`
(gentle sines, as in ``real_servos.py``), a small grid of light horns (inertia
ratio ``mu`` 0.01, 0.03, 0.1; restitution ``e`` 0.5, 0.8) each refits the loop's
rates, its friction, the play and the horn's friction ``al``; least squares
over everything (``mu``, ``e`` and ``al`` freed) starts from the best. It uses
the fit's private pieces, and lowers the inertia ratio's lower limit for this
process only.

Printed per record: the massless candidate's play and validation (over the
twin's floor), the light-horn fit's, and the validation change (positive:
the horn fits better). ``--own`` first checks the term on the model's own
simulation (a light horn with the twin's values, 4096-count quantisation and
0.3 count of noise): the massless fit's play, and the profile over the play
with the horn held at its truth.
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import replace

import numpy as np
from _table import table
from real_servos import NOISE_COUNTS, twin_record

from servoid.ident.metrics import nrmse
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import loop_fit as lf

#: The light horns tried: inertia ratios and restitutions (the twins' horns: 0.026 and about 0.78).
MU_GRID, E_GRID = (0.01, 0.03, 0.1), (0.5, 0.8)
#: The twins' horn, for the model's own simulation: inertia ratio, restitution, friction (rad/s^2).
TWIN_HORN = (0.026, 0.78, 20.0)


def _values(model: ServoLoopModel) -> dict[str, float]:
    """The fit's own names (``play``, ``asym``) for a fitted model."""
    d = {k: float(v) for k, v in model.params().items()}
    d["play"] = model.play
    d["asym"] = (model.c1 - model.c2) / (2.0 * model.play) if model.play > 0.0 else 0.0
    return d


def horn_fit(u: np.ndarray, y: np.ndarray, period: float) -> tuple[ServoLoopModel, float, ServoLoopModel, float, int]:
    """The massless play-in-loop candidate and the light-horn fit from it, with their validation NRMSE."""
    choice = lf.fit_loop(u, y, period)
    cand = min((c for c in choice.candidates if c.structure == PLAY_IN_LOOP), key=lambda c: c.validation_nrmse)
    uc, yc = u - float(np.mean(u)), y - float(np.mean(u))
    _, kv = lf._linear_start(uc, yc, period)
    a_scale = 0.1 * kv * float(np.std(np.diff(yc))) / period
    est = lf.block_mask(yc.size)
    d0 = _values(cand.model)
    best: tuple[float, dict[str, float]] | None = None
    sims = 0
    for mu in MU_GRID:
        for e in E_GRID:
            start = dict(d0, mu=mu, e=e, al=max(d0["fc"], 1.0))
            d, prob, sol = lf._fit(
                uc, yc, period, PLAY_IN_LOOP, start, est, a_scale, integrator=cand.integrator, max_nfev=12,
                free=("kp", "kv", "fc", "play", "al"),
            )  # fmt: skip
            sims += prob.evaluations
            cost = float(sol.cost) if sol is not None else np.inf
            if best is None or cost < best[0]:
                best = (cost, d)
    assert best is not None
    free = (*lf._free(PLAY_IN_LOOP, cand.integrator), "mu", "e", "al")
    d, prob, _ = lf._fit(
        uc, yc, period, PLAY_IN_LOOP, best[1], est, a_scale, integrator=cand.integrator, max_nfev=30, free=free
    )
    sims += prob.evaluations
    horn = lf._model(PLAY_IN_LOOP, period, d)
    y_hat = horn.simulate(uc, y0=float(yc[0]))
    return cand.model, cand.validation_nrmse, horn, nrmse(yc[~est], y_hat[~est]), sims


def own(spec: str) -> None:
    """The light horn on the model's own simulation: the massless fit's play, the profile with the horn held."""
    name, mult, seed = spec.split(":")
    rec = twin_record(name, float(mult), 1.0, "sines", int(seed))
    u, period, play = np.asarray(rec["u"]), float(rec["period"]), float(rec["play"])  # type: ignore[arg-type]
    massless, *_ = horn_fit(u, np.asarray(rec["y"]), period)
    mu, e, al = TWIN_HORN
    truth = replace(massless, mu=mu, e=e, al=al, c1=play / 2, c2=play / 2)
    uc = u - float(np.mean(u))
    q = 2.0 * np.pi / 4096
    y = truth.simulate(uc, y0=0.0) + np.random.default_rng(int(seed)).normal(0.0, NOISE_COUNTS * q, uc.size)
    y = np.round(y / q) * q
    floor = q * np.sqrt(1.0 / 12.0 + NOISE_COUNTS**2) / float(np.std(y))
    choice = lf.fit_loop(uc, y, period)
    print(
        f"\nThe model's own simulation (the {name} {mult}x s{seed} candidate's loop, a horn mu {mu}, e {e}, al {al}):"
    )
    print(
        f"  fit_loop (massless): {choice.structure}, play {100 * (choice.play / play - 1):+.1f} %, "
        f"validation {choice.validation_nrmse[choice.structure] / floor:.3f} x the floor"
    )
    _, kv = lf._linear_start(uc, y, period)
    a_scale = 0.1 * kv * float(np.std(np.diff(y))) / period
    est = lf.block_mask(y.size)
    d = _values(truth)
    free = tuple(f for f in lf._free(PLAY_IN_LOOP, False) if f != "play")
    rows = []
    for factor in (0.7, 0.85, 1.0, 1.15, 1.3):
        cells = []
        for start in (dict(d, play=factor * play), dict(d, play=factor * play, mu=0.0, e=0.0, al=0.0)):
            fitted, *_ = lf._fit(
                uc, y, period, PLAY_IN_LOOP, start, est, a_scale, integrator=False, max_nfev=60, free=free
            )
            y_hat = lf._model(PLAY_IN_LOOP, period, fitted).simulate(uc, y0=float(y[0]))
            cells.append(f"{nrmse(y[~est], y_hat[~est]) / floor:.3f}")
        rows.append([f"{factor:g}", *cells])
    table(
        "  the play held, the loop refitted: validation over the floor", ["play / truth", "horn held", "massless"], rows
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", default="sts3215:20:1,sts3215:20:2,xm430:20:1", help="preset:rate:seed, gentle sines")
    ap.add_argument("--own", action="store_true", help="first the check on the model's own simulation")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    lf._LOG_LIMITS["mu"] = (1e-3, 10.0)  # this process only: light horns
    specs = args.records.split(",")
    if args.own:
        own(specs[0])
    rows = []
    for spec in specs:
        name, mult, seed = spec.split(":")
        rec = twin_record(name, float(mult), 1.0, "sines", int(seed))
        play, floor = float(rec["play"]), float(rec["floor"])  # type: ignore[arg-type]
        started = time.perf_counter()
        massless, val0, horn, val1, sims = horn_fit(np.asarray(rec["u"]), np.asarray(rec["y"]), float(rec["period"]))  # type: ignore[arg-type]
        rows.append([
            name, f"{mult}x", seed, f"{100 * (massless.play / play - 1):+.1f} %", f"{val0 / floor:.3f}",
            f"{100 * (horn.play / play - 1):+.1f} %", f"{val1 / floor:.3f}", f"{100 * (val0 / val1 - 1):+.1f} %",
            f"{horn.mu:.3g}", f"{horn.e:.2f}", f"{horn.al:.3g}", str(sims), f"{time.perf_counter() - started:.1f}",
        ])  # fmt: skip
        print(" | ".join(rows[-1]), flush=True)
    table(
        "The play-in-loop candidate, massless and with a light horn (gap = play / the twin's - 1; validation / floor)",
        ["preset", "rate", "seed", "massless gap", "val", "horn gap", "val", "horn better by", "mu", "e", "al",
         "horn sims", "s (both)"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
