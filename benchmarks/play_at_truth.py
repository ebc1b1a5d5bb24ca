"""Is a play error the search's or the record's: the answer against the best fit with the play held at the truth.

Run: ``.venv/bin/python benchmarks/play_at_truth.py --presets odrive --rates 50 --seeds 2
[--noise-seeds 1,2,3] [--variant 'pos*0.5']``.

On each record (``real_servos.twin_record``: the table's gentle sines, 4096 counts, 0.3 count of
noise; ``--variant``: one of ``variants.py``'s one-parameter variants) :func:`~servoid.ident.offline.loop_fit.fit_loop`
as ``identify`` runs it (``load=None``, on the record centred as ``identify`` centres it) gives the answer. From the
answer's values with the play set to the twin's (its asymmetry kept); where the answer holds the play in the other
place than the twin, from the twin's place's best-validating candidate instead ("from"):

1. on the estimation blocks (:func:`~servoid.ident.offline.loop_fit.block_mask`), the answer's
   structure refitted with the play free and with it held at the truth: their validation rms
   errors over the floor ("val free", "val truth") and the latter's inertia ratio ("mu truth");
2. on every sample (the final refit's free parameters and budget), the fit with the play held at
   the truth: its cost above the answer's (fit_loop's own refit on every sample), in residual
   variances ("d cost truth": under about 3.84, the 95 % bound of one parameter, the record does
   not exclude the truth);
3. the held fit released (the play free again, on every sample): where its play ends and its cost
   against the answer's. A lower cost near the truth is a minimum the search missed; a return to
   the answer's play says the record's minimum is there (the model's bias or the noise draw).

The twins are not changed. Printed as measured; one run each (the machine may be shared).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from _table import table
from real_servos import twin_record
from variants import variants

from servoid.ident.models.servo_loop import LOAD_NAMES, ServoLoopModel
from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.horn_contact import _values


def refit_setup(
    u: np.ndarray, y: np.ndarray, period: float, model: ServoLoopModel
) -> tuple[np.ndarray, np.ndarray, float, tuple[str, ...], dict[str, float]]:
    """What refitting ``model`` (fit_loop's answer on ``u, y``) as fit_loop's final refit does needs: the record centred
    as fit_loop centres it, the scale of ``a0``, the final refit's free parameters and the answer's values."""
    centre = float(np.mean(u))
    uc, yc = np.ascontiguousarray(u - centre), np.ascontiguousarray(y - centre)
    _, kv = lf._linear_start(uc, yc, period)
    a_scale = 0.1 * kv * float(np.std(np.diff(yc))) / period
    free = lf._free(model.structure, model.ki > 0.0) + (LOAD_NAMES if model.massive else ())
    return uc, yc, a_scale, free, _values(model)


def row(name: str, mult: float, seed: int, noise: int | None, variant: str = "") -> list[str]:
    """One record: the answer's play and the fits with the play held at the truth and released (see the module)."""
    friction, over = next(((f, o) for label, f, o in variants(name) if label == variant), (1.0, {}))
    if variant and not over and friction == 1.0:
        raise SystemExit(f"variant {variant!r} is not one of {name}'s: {[v[0] for v in variants(name)]}")
    rec = twin_record(name, mult, friction, "sines", seed, noise, **over)
    u, y, period = np.asarray(rec["u"]), np.asarray(rec["y"]), float(rec["period"])  # type: ignore[arg-type]
    centre = float(np.mean(u))  # as identify centres the record: the search's path follows the last bits
    u, y = u - centre, y - centre
    truth = float(rec["play"])  # type: ignore[arg-type]
    t0 = time.perf_counter()
    choice = lf.fit_loop(u, y, period, load=None)
    model = choice.model
    uc, yc, a_scale, free, answer = refit_setup(u, y, period, model)
    # the fits at the truth in the twin's place: from the answer, or from that place's best candidate
    place = str(rec["structure"])
    inside = model
    if model.structure != place:
        inside = min((c for c in choice.candidates if c.structure == place), key=lambda c: c.validation_nrmse).model
    i_free = lf._free(place, inside.ki > 0.0) + (LOAD_NAMES if inside.massive else ())
    i_held = tuple(n for n in i_free if n != "play")
    at_truth = dict(_values(inside), play=truth)
    floor = float(rec["floor"]) * float(np.std(y))  # type: ignore[arg-type]
    est = lf.block_mask(yc.size)
    every = np.ones(yc.size, dtype=bool)

    def fit(
        start: dict[str, float], score: np.ndarray, names: tuple[str, ...], m: ServoLoopModel = model
    ) -> dict[str, float]:
        d, _, _ = lf._fit(uc, yc, period, m.structure, start, score, a_scale, integrator=m.ki > 0.0,
                          max_nfev=lf.FINAL_NFEV, free=names, ftol=lf.FTOL)  # fmt: skip
        return d

    def val(d: dict[str, float], m: ServoLoopModel = model) -> float:
        # the validation blocks' rms error over the floor (the unit of y)
        r = lf._model(m.structure, period, d).simulate(uc, y0=float(yc[0]))[~est] - yc[~est]
        return float(np.sqrt(np.mean(r**2))) / floor

    free_est, truth_est = fit(answer, est, free), fit(at_truth, est, i_held, inside)
    cost_answer = lf._cost(uc, yc, period, model.structure, answer, every)
    truth_all = fit(at_truth, every, i_held, inside)
    cost_truth = lf._cost(uc, yc, period, place, truth_all, every)
    released = fit(truth_all, every, i_free, inside)
    cost_released = lf._cost(uc, yc, period, place, released, every)
    variance = cost_answer / yc.size
    return [
        name + (f" {variant}" if variant else ""), f"{mult:g}x", str(seed) if noise is None else f"{seed}/{noise}",
        f"{model.mu:.2f}", f"{choice.play / truth - 1:+.1%}", model.structure if inside is model else f"{model.structure}; from {inside.play / truth:.2f}",
        f"{np.sqrt(cost_answer / yc.size) / floor:.3f}",
        f"{free_est['play'] / truth - 1:+.1%}", f"{val(free_est):.4f}", f"{val(truth_est, inside):.4f}", f"{truth_est.get('mu', 0.0):.2f}",
        f"{(cost_truth - cost_answer) / variance:+.1f}",
        f"{released['play'] / truth - 1:+.1%}", f"{(cost_released - cost_answer) / variance:+.1f}",
        f"{time.perf_counter() - t0:.0f}",
    ]  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="odrive,cia402")
    ap.add_argument("--rates", default="50")
    ap.add_argument("--seeds", default="2")
    ap.add_argument(
        "--noise-seeds", default="", help="comma-separated seeds of the encoders' noise (default: the record's)"
    )
    ap.add_argument("--variant", default="", help="one of variants.py's labels, e.g. 'pos*0.5' (default: the preset)")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    noises: list[int | None] = [int(s) for s in args.noise_seeds.split(",") if s.strip()] or [None]
    rows = []
    for name in args.presets.split(","):
        for mult in (float(r) for r in args.rates.split(",")):
            for seed in (int(s) for s in args.seeds.split(",")):
                for noise in noises:
                    rows.append(row(name, mult, seed, noise, args.variant))
                    print(" | ".join(rows[-1]), flush=True)
    table(
        "fit_loop's answer against the play held at the truth (validation over the floor; costs in residual variances)",
        ["preset", "rate", "seed(/noise)", "mu", "answer", "place", "rms/floor", "est: free play", "val free", "val truth", "mu truth",
         "d cost truth", "released: play", "d cost", "s"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
