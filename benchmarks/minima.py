"""Where the servo-loop fit's answer scatters from (issue 12): its minima, and the twin's effects one at a time.

Run: ``.venv/bin/python benchmarks/minima.py --presets odrive,cia402 --rates 20 --seeds 1 [--starts 6]
[--effects] [--fine]``.

1. **Minima.** On one twin record (``real_servos.py``'s gentle sines), :func:`fit_loop` answers;
   its final model is then refitted on every sample from ``--starts`` starts around it (each rate,
   friction, speed and the load's values times ``exp(N(0, 0.15))``, the play times
   ``exp(U(+-0.25))``; the load's values free as in :func:`fit_loop`'s final refit of a kept load),
   and each minimum's cost, play and fit are printed. A minimum's cost above the lowest is given in
   units of the residual variance ``sigma^2`` (the lowest cost over ``n``), the likelihood ratio of
   the two under white Gaussian errors: within :data:`LR95` (chi-square, one degree of freedom, 95 %)
   the data do not tell the two apart and the interval must hold both plays; far beyond it the
   search stopped early and the lowest one is the data's answer. (The residuals are correlated, so
   the ratio overstates the evidence: a bound, not a test.)
2. **Effects** (``--effects``). The same record from the twin with one of its effects scaled
   (stiffer gear, lossless gear, less load or motor friction ...); :func:`fit_loop` on each. With
   ``--fine`` the output encoder has 2**20 counts and no noise, so that the model's error shows
   above the floor (``rms/play``: the fit's RMS error over the true play).

Both print as they are; the twins' physics and presets are not changed (only this run's copies).
The machine may be shared: times are one run each.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np
from _table import table
from real_servos import BANDWIDTH_HZ, DURATION_S, MAX_SAMPLES, NOISE_COUNTS, SINE_AMPLITUDE
from twin_effects import effects

from servoid.drivers.twin import Twin, preset
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.models.servo_loop import LOAD_NAMES
from servoid.ident.offline.load_stage import MU_LIMITS
from servoid.ident.offline.loop_fit import _LOG, _fit, _free, _linear_start, _model, fit_loop

#: Spread of the starts around the answer: log-normal on the positive values, uniform in log on the play.
SPREAD, PLAY_SPREAD = 0.15, 0.25
#: The refits' budget (scipy's ``max_nfev``) and ``ftol``: run to their minimum, not to fit_loop's stop rules.
NFEV, FTOL = 60, 1e-8
#: The 95 % point of chi-square with one degree of freedom.
LR95 = 3.84


def record(name: str, mult: float, seed: int, fine: bool, extra: dict[str, float]) -> dict[str, Any]:
    """``real_servos.twin_record``'s gentle sines, from a twin with ``extra`` overrides (and a fine encoder)."""
    over: dict[str, float] = {
        "encoder_noise_counts": 0.0 if fine else NOISE_COUNTS,
        "load_encoder_cpr": 2**20 if fine else 4096,
    }
    over.update(extra)
    twin = Twin(preset(name, **over), seed=seed)
    twin.enable()
    rate = mult * BANDWIDTH_HZ[name]
    n = int(min(DURATION_S * rate, MAX_SAMPLES))
    u = sample(GentleSpec(amplitude=SINE_AMPLITUDE[name], accel=8.0 / rate**2, spread=8.0), n, seed=seed + 1000)
    rec = twin.sample(u, 1.0 / rate)
    y = np.asarray(rec.y, dtype=np.float64)
    q = twin.truth.output_rad_per_count
    floor = q * math.sqrt(1.0 / 12.0 + over["encoder_noise_counts"] ** 2)  # rms, rad
    return {"u": np.asarray(rec.u, dtype=np.float64), "y": y, "period": 1.0 / rate, "play": twin.truth.play_rad, "floor": floor}  # fmt: skip


def minima(rec: dict[str, Any], starts: int, label: str) -> list[list[str]]:
    """The answer of :func:`fit_loop` and its refits from ``starts`` starts around it: one row each."""
    u, y, period, true = rec["u"], rec["y"], rec["period"], rec["play"]
    t0 = time.perf_counter()
    choice = fit_loop(u, y, period, load=None)
    m = choice.model
    centre = float(np.mean(u))
    uc, yc = u - centre, y - centre
    kept = np.ones(y.size, dtype=bool)
    _, kv = _linear_start(uc, yc, period)
    a_scale = 0.1 * kv * float(np.std(np.diff(yc))) / period
    d0 = dict(m.params(), play=m.play, asym=m.c1 / m.play - 0.5 if m.play > 0 else 0.0)
    d0.update({n: d0.get(n, 0.0) for n in LOAD_NAMES})
    free = _free(m.structure, m.ki > 0.0) + (LOAD_NAMES if m.massive else ())
    rng = np.random.default_rng(0)
    found = []
    for i in range(starts + 1):
        s = dict(d0)
        if i:
            for n in free:
                if n in _LOG and n != "play":
                    s[n] *= math.exp(rng.normal(0.0, SPREAD))
            s["play"] *= math.exp(rng.uniform(-PLAY_SPREAD, PLAY_SPREAD))
            if m.massive:
                s["mu"] = min(max(s["mu"], MU_LIMITS[0]), MU_LIMITS[1])
        d, prob, _ = _fit(uc, yc, period, m.structure, s, kept, a_scale, integrator=m.ki > 0.0, max_nfev=NFEV, free=free, ftol=FTOL)  # fmt: skip
        fitted = _model(m.structure, period, d)
        r = fitted.simulate(uc, y0=float(yc[0])) - yc
        found.append((float(r @ r), s["play"], fitted, prob.evaluations))
    best = min(c for c, *_ in found)
    sigma2 = best / y.size
    rows = []
    for i, (cost, start_play, fitted, used) in enumerate(found):
        rows.append([
            label, "answer" if i == 0 else str(i), f"{start_play / true - 1:+.1%}", f"{fitted.play / true - 1:+.1%}",
            f"{(cost - best) / sigma2:.1f}", f"{math.sqrt(cost / y.size) / rec['floor']:.3f}",
            f"{fitted.mu:.2f}" if fitted.massive else "-", str(used),
        ])  # fmt: skip
    same = [f.play / true - 1 for c, _, f, _ in found if c - best <= LR95 * sigma2]
    print(
        f"{label}: fit_loop {choice.play / true - 1:+.1%}; minima within the 95 % likelihood ratio of the lowest: {len(same)} of "
        f"{len(found)}, plays {min(same):+.1%} ... {max(same):+.1%}; lowest {found[int(np.argmin([c for c, *_ in found]))][2].play / true - 1:+.1%} "
        f"({time.perf_counter() - t0:.0f} s)",
        flush=True,
    )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="odrive,cia402")
    parser.add_argument("--rates", default="20")
    parser.add_argument("--seeds", default="1")
    parser.add_argument("--starts", type=int, default=6)
    parser.add_argument("--effects", action="store_true", help="fit_loop on the twin with each effect scaled")
    parser.add_argument("--fine", action="store_true", help="a 2**20-count output encoder without noise")
    args = parser.parse_args()
    runs = [(p, float(r), int(s)) for p in args.presets.split(",") for r in args.rates.split(",") for s in args.seeds.split(",")]  # fmt: skip
    rows: list[list[str]] = []
    for name, mult, seed in runs:
        label = f"{name} {mult:g}x s{seed}"
        rows += minima(record(name, mult, seed, args.fine, {}), args.starts, label)
    head = ["record", "start", "start play", "play", "cost - lowest (sigma^2)", "rms / floor", "mu", "simulations"]
    table("Minima: fit_loop's answer refitted from starts around it (gap = play / true - 1)", head, rows)
    if not args.effects:
        return
    rows = []
    for name, mult, seed in runs:
        for what, extra in effects(name).items():
            rec = record(name, mult, seed, args.fine, extra)
            t0 = time.perf_counter()
            c = fit_loop(rec["u"], rec["y"], rec["period"], load=None)
            rms = c.fit_nrmse * float(np.std(rec["y"]))
            rows.append([
                f"{name} {mult:g}x s{seed}", what, c.structure, f"{c.play / rec['play'] - 1:+.1%}", f"{rms / rec['floor']:.2f}",
                f"{rms / rec['play']:.3f}", f"{c.model.mu:.2f}" if c.model.massive else "-", f"{time.perf_counter() - t0:.0f}",
            ])  # fmt: skip
            print(" | ".join(rows[-1]), flush=True)
    title = (
        f"Effects one at a time ({'2**20-count encoder, no noise' if args.fine else '4096 counts, 0.3 count noise'})"
    )
    table(title, ["record", "twin", "structure", "gap", "rms / floor", "rms / play", "mu", "s"], rows)


if __name__ == "__main__":
    main()
