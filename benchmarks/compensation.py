"""Backlash compensation on the simulated servo: improvement, robustness, cost per sample.

Run: ``.venv/bin/python benchmarks/compensation.py`` (a few seconds). Prints three tables:

1. RMS tracking error over the five reference paths of ``servoid compensate``
   on the paper's plant, uncompensated against the smoothed inverse, for
   several integral gains and measurement noise levels (encoder step 0.0075,
   band by servoid's rule ``max(0.02 (c1 + c2), 2 noise_std)``);
2. the ratio with the controller's dead zones (and all parameters) off by
   -20 .. +20 %;
3. the cost of one online step of the inverse and of the whole controller.

Ratios marked ``>=`` are limited by the encoder's resolution.
"""

from __future__ import annotations

import time

from servoid.ident import PAPER_PLANT
from servoid.ident.control.compensate import BacklashInverse, InverseParams, default_band
from servoid.ident.control.compensation_study import compensation_study
from servoid.ident.control.tracking import Sensor, TrackingController

RESOLUTION = 0.0075


def _row(cells: list[str], widths: list[int]) -> str:
    return "  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(cells, widths)))


def improvement_table() -> None:
    print("1. nominal model, all paths: RMS uncompensated -> smoothed inverse (ratio)")
    widths = [10, 8, 8, 30]
    print(_row(["noise std", "band", "k_i", "RMS unc -> inv (ratio)"], widths))
    for noise in (0.0, 0.01, 0.03):
        band = default_band(PAPER_PLANT, noise_std=noise)
        for ki in (0.1, 0.25, 0.4):
            study = compensation_study(PAPER_PLANT, band=band, integral_gain=ki, changes=(),
                                       sensor=Sensor(resolution=RESOLUTION, noise_std=noise, seed=1))  # fmt: skip
            before, after = study.summary("uncompensated"), study.summary("compensated")
            ratio = study.rms_improvement(before, after)
            cell = f"{before.rms_error:.3g} -> {after.rms_error:.3g} ({ratio})"
            print(_row([f"{noise:g}", f"{band:.3g}", f"{ki:g}", cell], widths))
    print()


def robustness_table() -> None:
    print("2. controller's model perturbed (servo unchanged), noise 0.01, k_i 0.25: RMS ratio naive / smoothed,")
    print("   and motor travel per unit of reference travel (naive / smoothed; uncompensated ~1.7)")
    noise = 0.01
    study = compensation_study(PAPER_PLANT, band=default_band(PAPER_PLANT, noise_std=noise),
                               sensor=Sensor(resolution=RESOLUTION, noise_std=noise, seed=1))  # fmt: skip
    widths = [12, 22, 18]
    print(_row(["model", "RMS ratio naive / inv", "travel naive / inv"], widths))
    rows = [("nominal", {a: study.summary(a) for a in ("uncompensated", "naive", "compensated")})]
    rows += [(p.label, p.summaries) for p in study.perturbations]
    for label, s in rows:
        naive = study.rms_improvement(s["uncompensated"], s["naive"])
        inv = study.rms_improvement(s["uncompensated"], s["compensated"])
        travel = f"{s['naive'].motor_travel:.1f} / {s['compensated'].motor_travel:.1f}"
        print(_row([label, f"{naive} / {inv}", travel], widths))
    print()


def cost_table() -> None:
    print("3. cost of one online step (pure Python, this machine)")
    n = 200_000
    inverse = BacklashInverse(InverseParams.from_model(PAPER_PLANT, band=0.03))
    values = [0.5 * ((k % 200) / 100.0 - 1.0) for k in range(n)]
    start = time.perf_counter()
    for v in values:
        inverse.step(v)
    per_inverse = (time.perf_counter() - start) / n
    controller = TrackingController(PAPER_PLANT, inverse=InverseParams.from_model(PAPER_PLANT, band=0.03))
    start = time.perf_counter()
    for v in values:
        controller.step(v, v)
    per_controller = (time.perf_counter() - start) / n
    print(f"   BacklashInverse.step      {per_inverse * 1e6:6.2f} us")
    print(f"   TrackingController.step   {per_controller * 1e6:6.2f} us  (feedforward + integral + inverse)")


if __name__ == "__main__":
    improvement_table()
    robustness_table()
    cost_table()
