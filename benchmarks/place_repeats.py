"""Is a horn row's place a property of the record or of its noise draw: the place evidence over repeats.

Run: ``.venv/bin/python benchmarks/place_repeats.py --presets xm430 --rates 10,50 --seeds 2 --noise-seeds 11,12``
(``--variant LABEL``: one of ``variants.py``'s one-parameter variants; the record's own noise draw is always run
first).

Each record is ``real_servos.twin_record``'s (the table's gentle sines, 4096 counts, 0.3 count of noise); a
noise seed draws the encoders' noise again over the same set point. ``identify`` with no flags answers; from
the servo-loop fit it ran (``fit_loop``'s best candidate of each place, on the record as ``identify`` centred it)
the table prints, besides the answer, its place (named / undetermined / WRONG) and the two numbers the place
rule reads (the validation margin and the catch-up statistic ``place_z``,
:func:`~servoid.ident.offline.place_test.reversal_z`):

- ``detect``: what the catch-ups could show if the winner were the servo. The two places' free runs differ
  by ``D`` on the catch-ups (:func:`~servoid.ident.offline.place_test.catch_up_groups`); with the winner right
  and white noise of the winner's validation RMS ``sigma``, the statistic would be about
  ``sqrt(sum D^2) / (2 sigma)`` (one-sided 2.33 names the place). A record whose ``place_z`` sits well under
  it misses an effect where the places differ (both fits miss it there).
- ``diff``: the RMS of ``D`` on the validation blocks, in counts of the encoder, against ``sigma`` in counts.
- ``catch-up``: model-free, the median over the output's turns (by more than 3 counts) of the output's
  move over one loop time constant ``1/kp`` from where it leaves its extreme (by 1.5 counts), over the
  set point's move over the same samples. A loop closed on the output around a play drives the motor
  through the play while the output waits and the output then catches up (above 1); a loop closed on the
  motor does not (at or under 1, the loop's lag).

Printed as measured; one run each (the machine may be shared). No twin is changed.
"""

from __future__ import annotations

import argparse
import importlib
import math
import warnings
from typing import Any

import numpy as np
from _table import table
from real_servos import run as identify_run
from real_servos import twin_record
from variants import variants

from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
from servoid.ident.offline.intervals import quantum, reversal_indices
from servoid.ident.offline.loop_fit import block_mask
from servoid.ident.offline.place_test import catch_up_groups

_IDENTIFY = importlib.import_module("servoid.ident.identify")  # the module (the package exports the function)


def _with_loop_input(u: np.ndarray, y: np.ndarray, period: float) -> tuple[Any, dict[str, Any]]:
    """identify's answer, and the record as its servo-loop fit saw it (``identify`` centres it first)."""
    seen: dict[str, Any] = {}
    fit = _IDENTIFY.second_structure

    def spy(uc: Any, yc: Any, h: float, keep: Any = None) -> Any:
        seen.update(u=np.array(uc), y=np.array(yc), period=h)
        return fit(uc, yc, h, keep=keep)

    _IDENTIFY.second_structure = spy
    try:
        result, _ = identify_run(u, y, period)
    finally:
        _IDENTIFY.second_structure = fit
    return result, seen


def detectability(loop: Any, seen: dict[str, Any]) -> tuple[float, float, float]:
    """``(detect, diff, sigma)`` of the module's text, from ``fit_loop``'s candidates (diff, sigma in counts).

    The candidates are scored as ``fit_loop`` scored them: the record centred on the set point's mean,
    the validation blocks of the whole record (the twins' records are shorter than its search window).
    """
    centre = float(np.mean(seen["u"]))
    u, y = seen["u"] - centre, seen["y"] - centre
    best = {s: min((c for c in loop.candidates if c.structure == s), key=lambda c: c.validation_nrmse)
            for s in (OUTPUT_BACKLASH, PLAY_IN_LOOP)}  # fmt: skip
    win = best[loop.structure]
    rival = best[OUTPUT_BACKLASH if loop.structure == PLAY_IN_LOOP else PLAY_IN_LOOP]
    val = ~block_mask(y.size)
    y_win, y_rival = (c.model.simulate(u, y0=float(y[0])) for c in (win, rival))
    span = math.ceil(1.0 / (win.model.kp * seen["period"])) if win.model.kp > 0.0 else 0
    groups = catch_up_groups(y_win, win.model.play, span, val)
    d = y_rival - y_win
    sigma = float(np.sqrt(np.mean((y_win - y)[val] ** 2)))
    q = quantum(y)
    signal = math.sqrt(sum(float(np.sum(d[g] ** 2)) for g in groups))
    return signal / (2.0 * sigma), float(np.sqrt(np.mean(d[val] ** 2))) / q, sigma / q


def catch_up_ratio(u: np.ndarray, y: np.ndarray, period: float, kp: float) -> float:
    """The model-free catch-up of the module's text: median output move over set-point move after each turn."""
    q = quantum(y)
    span = max(2, math.ceil(1.0 / (kp * period)))
    ratios = []
    for t in reversal_indices(y, 3.0 * q):
        s = 1.0 if y[t] > y[t - 1] else -1.0  # the new direction
        lo = max(0, int(t) - 10 * span)
        seg = y[lo : t + 1]
        extreme = lo + int(np.argmin(seg) if s > 0 else np.argmax(seg))
        leave = extreme
        while leave < t and s * (y[leave] - y[extreme]) <= 1.5 * q:
            leave += 1
        if leave + span >= y.size:
            continue
        moved = s * (u[leave + span] - u[leave])
        if moved > 2.0 * q:
            ratios.append(s * (y[leave + span] - y[leave]) / moved)
    return float(np.median(ratios)) if ratios else math.nan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="xm430")
    ap.add_argument("--rates", default="10,20,50")
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--noise-seeds", default="", help="more noise draws of each record (comma-separated)")
    ap.add_argument("--variant", default="", help="one of variants.py's labels, e.g. 'fric*4'")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    cols = ["preset", "rate", "seed", "noise", "answer", "gap", "place", "margin", "place z", "detect",
            "diff / sigma (counts)", "catch-up"]  # fmt: skip
    rows: list[list[str]] = []
    for name in args.presets.split(","):
        friction, over = 1.0, {}
        if args.variant:
            friction, over = next((f, o) for label, f, o in variants(name) if label == args.variant)
        for mult in (float(r) for r in args.rates.split(",")):
            for seed in (int(s) for s in args.seeds.split(",")):
                for noise in [None, *(int(n) for n in args.noise_seeds.split(",") if n)]:
                    rec = twin_record(name, mult, friction, "sines", seed, noise_seed=noise, **over)
                    result, seen = _with_loop_input(rec["u"], rec["y"], rec["period"])  # type: ignore[arg-type]
                    loop = result.loop
                    gap = 100.0 * (result.play / float(rec["play"]) - 1.0)  # type: ignore[arg-type]
                    if result.verdict.structure_undetermined:
                        place = "undetermined"
                    else:
                        place = "named" if result.structure == rec["structure"] else "WRONG"
                    row = [name, f"{mult:g}x", str(seed), "own" if noise is None else str(noise), result.structure,
                           f"{gap:+.1f} %", place]  # fmt: skip
                    if loop is None or not seen:
                        rows.append([*row, "", "", "", "", ""])
                    else:
                        detect, diff, sigma = detectability(loop, seen)
                        kp = float(np.median([c.model.kp for c in loop.candidates]))
                        ratio = catch_up_ratio(seen["u"], seen["y"], seen["period"], kp)
                        rows.append([*row, f"{100.0 * loop.margin:.1f} %", f"{loop.place_z:+.2f}", f"{detect:.2f}",
                                     f"{diff:.2f} / {sigma:.2f}", f"{ratio:.2f}"])  # fmt: skip
                    print(" | ".join(rows[-1]), flush=True)
    table("The place of the play over noise draws (identify, no flags; place z >= 2.33 or margin >= 5 % names "
          "a play in the loop)", cols, rows)  # fmt: skip


if __name__ == "__main__":
    main()
