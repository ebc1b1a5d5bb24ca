"""Does the ODrive's motor-side play error follow its gear's compliance (issue 12, the gear's windup)?

Run: ``.venv/bin/python benchmarks/windup.py --presets odrive --rates 10,20,50 --seeds 1,2,3,4,5,6
[--variants as-is,stiff,soft,damped] [--spring] [--dump out.jsonl]``; ``--load out.jsonl`` prints the tables of a dump again.

On each record (``real_servos.twin_record``: the table's gentle sines, 4096 counts, 0.3 count of noise),
``identify`` with no flags, once per variant of the twin, one effect at a time:

- ``as-is``: the preset;
- ``stiff``: the gear 100 times stiffer, its damping 10 times (the same damping ratio);
- ``soft``: the gear half as stiff, its damping / sqrt 2 (the same damping ratio);
- ``damped``: the gear as stiff, its damping 20 times (the ODrive's about critical: the same windup, no ringing);

and the quasi-static windup the gear adds to each flank, ``(J_load a + T_load) / k`` at the set point's rms
acceleration, as a share of the play. Printed per record: the gap, the load stage's inertia ratio (0: the
massless answer), the fit over the floor; then per variant: within 5 %, mean, standard deviation, largest.
If the rigid flanks book the windup as play, the gap moves with ``1 / k`` (two flanks: two windups).
The twins' presets are not changed (overrides on one record each).

``--spring``: instead, on each record (each variant), a gear windup the record places, as a prototype (the
library is not changed): ``fit_loop`` as ``identify`` runs it (the record centred as ``identify`` centres it), then
its answer refitted on every sample (the final refit's free parameters, budget and stop) with the reading taken off
by the quasi-static windup of a spring between the play and the load,
``y_read = y - (y'' + al sat(y' / veps)) / wc^2`` (``y''``: the load's acceleration, ``al sat``: its friction, as
the model's load has them; the spring's force over the load's inertia is the load's own equation of motion, so
only ``wc``, the spring's frequency on the load's inertia, is new), ``wc`` held at each of :data:`WCS` (rigid
first) and then free from the best. Printed: each fit's cost on every sample in residual variances against the
answer's, its play, and the free ``wc``; the summary as above for the answer, the rigid refit, the spring free,
and the spring kept only where it lowers the rigid refit's cost by more than ``ln(n)`` variances (BIC, one
parameter; elsewhere the answer).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import time
import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np
from _table import table
from play_at_truth import refit_setup
from real_servos import run, twin_record

from servoid.drivers.twin import preset
from servoid.ident.models.servo_loop import KERNEL_NAMES, simulate_kernel, simulate_pair_kernel
from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.operating_point import operating_point

#: The variants: overrides of the gear's stiffness and damping as factors of the preset's.
VARIANTS = {"as-is": (1.0, 1.0), "stiff": (100.0, 10.0), "soft": (0.5, 0.5**0.5), "damped": (1.0, 20.0)}
#: Samples of the record's start left out of its rms acceleration (the set point's first step into its speed).
START = 10


def _overrides(name: str, variant: str) -> dict[str, float]:
    """The twin's gear stiffness and damping under ``variant`` (:data:`VARIANTS`)."""
    base = preset(name)
    k_factor, c_factor = VARIANTS[variant]
    return {
        "gear_stiffness_nm_rad": base.gear_stiffness_nm_rad * k_factor,
        "gear_damping_nms": base.gear_damping_nms * c_factor,
    }


def record(name: str, mult: float, seed: int, variant: str) -> dict[str, Any]:
    """One record's answer under one variant: gap, inertia ratio, fit over the floor, seconds, windup share."""
    base = preset(name)
    k_factor = VARIANTS[variant][0]
    rec = twin_record(name, mult, 1.0, "sines", seed, **_overrides(name, variant))
    u, y, period = rec["u"], rec["y"], rec["period"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result, seconds = run(u, y, period)  # type: ignore[arg-type]
    truth = float(rec["play"])  # type: ignore[arg-type]
    loop = result.loop
    mu = float(loop.model.mu) if loop is not None else math.nan
    fit = (float(loop.fit_nrmse) if loop is not None else float(result.fit_nrmse)) / float(rec["floor"])  # type: ignore[arg-type]
    # the set point's rms acceleration at the output (the load follows it) and the windup it takes per flank
    # (past the start, where the set point steps into its first speed)
    acc = float(np.sqrt(np.mean(np.diff(np.asarray(u)[START:], 2) ** 2))) / float(period) ** 2  # type: ignore[arg-type]
    k = base.gear_stiffness_nm_rad * k_factor
    windup = (base.load_inertia_kgm2 * acc + base.load_coulomb_nm) / k
    return {
        "preset": name, "mult": mult, "seed": seed, "variant": variant,
        "gap": result.play / truth - 1.0, "mu": mu, "fit": fit, "s": seconds,
        "windup": windup / truth, "structure": result.structure,
    }  # fmt: skip


#: ``--spring``: the spring's frequencies on the load's inertia, rad/s, the answer is refitted at (rigid first). The
#: ODrive twin's gear on its load: sqrt(800 / 0.02) = 200 rad/s; the CiA 402 twin's: sqrt(75 630 / 0.02) = 1945 rad/s.
WCS = (math.inf, 400.0, 283.0, 200.0, 141.0, 100.0)
_NK = len(KERNEL_NAMES)
_AL, _VEPS = KERNEL_NAMES.index("al"), KERNEL_NAMES.index("veps")


def windup_reading(y: np.ndarray, p: np.ndarray, period: float) -> np.ndarray:
    """``y`` (the model's load at the host instants) less the spring's quasi-static windup, in place.

    ``p`` is the kernel's vector with the spring's compliance over the load's inertia, ``1 / wc^2`` (s^2), appended
    (0: rigid). The spring carries the load's inertia and friction, ``y'' + al sat(y' / veps)`` per the load's
    inertia (0 in free flight, where the load's own friction is all that acts on it): central differences at the
    host rate.
    """
    cg = float(p[_NK])
    if cg > 0.0:
        al, veps = float(p[_AL]), float(p[_VEPS])
        v, a = np.zeros_like(y), np.zeros_like(y)
        v[1:-1] = (y[2:] - y[:-2]) / (2.0 * period)
        a[1:-1] = (y[2:] - 2.0 * y[1:-1] + y[:-2]) / period**2
        y -= cg * (a + al * np.clip(v / veps, -1.0, 1.0))
    return y


class _SpringProblem(lf._Problem):
    """``fit_loop``'s problem with the spring's compliance ``cg`` (``1 / wc^2``) read off the simulated load."""

    def vector(self, z: np.ndarray) -> np.ndarray:
        return np.r_[super().vector(z), self.values(z).get("cg", 0.0)]

    def simulate(self, p: np.ndarray, buffer: np.ndarray | None = None) -> np.ndarray:
        out = self.buffer if buffer is None else buffer
        simulate_kernel(p[:_NK].copy(), self.feedback_load, self.u, float(self.y[0]), self.period, self.m, out)
        return windup_reading(out, p, self.period)

    def simulate_pair(self, p: np.ndarray, q: np.ndarray, buffers: tuple[np.ndarray, np.ndarray]) -> None:
        simulate_pair_kernel(
            p[:_NK].copy(), q[:_NK].copy(), self.feedback_load, self.u, float(self.y[0]), self.period, self.m, *buffers
        )  # fmt: skip
        windup_reading(buffers[0], p, self.period)
        windup_reading(buffers[1], q, self.period)


@contextlib.contextmanager
def _spring_fits() -> Iterator[None]:
    """``loop_fit``'s fits with the spring (:class:`_SpringProblem`; ``cg`` fitted as a log), for the block only."""
    problem, log = lf._Problem, lf._LOG
    lf._Problem, lf._LOG = _SpringProblem, frozenset(log | {"cg"})  # type: ignore[misc]
    try:
        yield
    finally:
        lf._Problem, lf._LOG = problem, log  # type: ignore[misc]


def spring_record(name: str, mult: float, seed: int, variant: str) -> dict[str, Any]:
    """One record: the answer, its refits on every sample with the spring held at each of :data:`WCS`, and free."""
    rec = twin_record(name, mult, 1.0, "sines", seed, **_overrides(name, variant))
    truth, period = float(rec["play"]), float(rec["period"])  # type: ignore[arg-type]
    u, y = (np.asarray(a) for a in operating_point(rec["u"], rec["y"]).centre(rec["u"], rec["y"]))  # type: ignore[arg-type]
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        choice = lf.fit_loop(u, y, period, load=None)
    seconds = time.perf_counter() - t0
    model = choice.model
    uc, yc, a_scale, free, answer = refit_setup(u, y, period, model)
    answer["cg"] = 0.0
    every = np.ones(yc.size, dtype=bool)
    row: dict[str, Any] = {
        "preset": name, "mult": mult, "seed": seed, "variant": variant, "n": int(yc.size), "gap": choice.play / truth - 1.0,
        "mu": float(model.mu), "s": seconds, "held": {},
    }  # fmt: skip
    with _spring_fits():

        def cost(d: dict[str, float]) -> float:
            return lf._cost(uc, yc, period, model.structure, d, every)

        def refit(wc: float, names: tuple[str, ...]) -> tuple[dict[str, float], float]:
            t1 = time.perf_counter()
            d, _, _ = lf._fit(uc, yc, period, model.structure, dict(answer, cg=1.0 / wc**2), every, a_scale,
                              integrator=model.ki > 0.0, max_nfev=lf.FINAL_NFEV, free=names, ftol=lf.FTOL,
                              stall=lf.FINAL_STALL)  # fmt: skip
            return d, time.perf_counter() - t1

        base = cost(answer)
        variance = base / yc.size
        for wc in WCS:
            d, t = refit(wc, free)
            row["held"][str(wc)] = [(cost(d) - base) / variance, d["play"] / truth - 1.0, t]
        best = min(WCS[1:], key=lambda wc: row["held"][str(wc)][0])
        d, t = refit(best, free + ("cg",))
        wc_free = 1.0 / math.sqrt(d["cg"]) if d["cg"] > 0.0 else math.inf
        row["free"] = [(cost(d) - base) / variance, d["play"] / truth - 1.0, wc_free, t]
    return row


def _pays(row: dict[str, Any]) -> bool:
    """Whether the spring lowers the rigid refit's cost by more than ``ln(n)`` variances (BIC, one parameter)."""
    return bool(row["free"][0] < row["held"][str(math.inf)][0] - math.log(row["n"]))


def _paid(row: dict[str, Any]) -> float:
    """The spring's play where it pays (:func:`_pays`), else the answer's."""
    return float(row["free"][1] if _pays(row) else row["gap"])


def spring_tables(rows: list[dict[str, Any]]) -> None:
    """``--spring``'s per-record table and its summary."""
    table(
        "The answer refitted on every sample with the spring held at wc (cost in residual variances against the "
        "answer's / play error), and free",
        ["preset", "variant", "rate", "seed", "answer", "mu", *(f"wc {wc:g}" for wc in WCS), "free wc", "free", "s"],
        [[r["preset"], r["variant"], f"{r['mult']:g}x", str(r["seed"]), f"{100 * r['gap']:+.1f} %", f"{r['mu']:.2f}",
          *(f"{r['held'][str(wc)][0]:+.0f} / {100 * r['held'][str(wc)][1]:+.1f} %" for wc in WCS),
          f"{r['free'][2]:.0f}", f"{r['free'][0]:+.0f} / {100 * r['free'][1]:+.1f} %",
          f"{r['s']:.1f} + {sum(h[2] for h in r['held'].values()) + r['free'][3]:.1f}"] for r in rows],
    )  # fmt: skip
    out = []
    for key in dict.fromkeys((r["preset"], r["variant"]) for r in rows):
        group = [r for r in rows if (r["preset"], r["variant"]) == key]
        kept = sum(1 for r in group if _pays(r))
        estimators = {
            "the answer": [r["gap"] for r in group],
            "the rigid refit": [r["held"][str(math.inf)][1] for r in group],
            "the spring free": [r["free"][1] for r in group],
            f"the spring where it pays (BIC: {kept})": [_paid(r) for r in group],
        }
        for name, gaps in estimators.items():
            g = np.array(gaps)
            out.append([*key, name, str(g.size), str(int(np.sum(np.abs(g) <= 0.05))), f"{100 * g.mean():+.1f} %",
                        f"{100 * g.std(ddof=1) if g.size > 1 else 0.0:.1f} %", f"{100 * np.abs(g).max():.1f} %"])  # fmt: skip
    table("Gaps over the records", ["preset", "variant", "estimator", "records", "within 5 %", "mean", "sd",
          "largest"], out)  # fmt: skip


def summary(rows: list[dict[str, Any]]) -> list[list[str]]:
    """Per preset and variant: records, within 5 %, mean, standard deviation, largest |gap|, windup share."""
    out = []
    keys = sorted({(r["preset"], r["variant"]) for r in rows}, key=lambda k: (k[0], list(VARIANTS).index(k[1])))
    for name, variant in keys:
        g = np.array([r["gap"] for r in rows if r["preset"] == name and r["variant"] == variant])
        w = np.array([r["windup"] for r in rows if r["preset"] == name and r["variant"] == variant])
        out.append([
            name, variant, str(g.size), str(int(np.sum(np.abs(g) <= 0.05))), f"{100 * g.mean():+.1f} %",
            f"{100 * g.std(ddof=1) if g.size > 1 else 0.0:.1f} %", f"{100 * np.abs(g).max():.1f} %",
            f"{100 * np.median(w):.1f} %",
        ])  # fmt: skip
    return out


def print_tables(rows: list[dict[str, Any]]) -> None:
    """The per-record table and the summary."""
    table(
        "Per record (identify, no flags)",
        ["preset", "rate", "seed", "variant", "gap", "mu", "fit/floor", "windup/play", "s"],
        [[r["preset"], f"{r['mult']:g}x", str(r["seed"]), r["variant"], f"{100 * r['gap']:+.1f} %", f"{r['mu']:.2f}",
          f"{r['fit']:.2f}", f"{100 * r['windup']:.1f} %", f"{r['s']:.1f}"] for r in rows],
    )  # fmt: skip
    table(
        "Per variant: gaps over the records", ["preset", "variant", "records", "within 5 %", "mean", "sd", "largest",
        "windup/play"], summary(rows),
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="odrive")
    parser.add_argument("--rates", default="10,20,50")
    parser.add_argument("--seeds", default="1,2,3,4,5,6")
    parser.add_argument("--variants", default="as-is,stiff")
    parser.add_argument("--spring", action="store_true", help="the gear windup the record places (see the module)")
    parser.add_argument("--dump", default=None)
    parser.add_argument("--load", default=None)
    args = parser.parse_args()
    if args.load:
        with open(args.load) as f:
            loaded = [json.loads(line) for line in f]
        (spring_tables if "free" in loaded[0] else print_tables)(loaded)
        return
    rows = []
    for name in args.presets.split(","):
        for mult in (float(m) for m in args.rates.split(",")):
            for seed in (int(s) for s in args.seeds.split(",")):
                for row in (
                    [(spring_record if args.spring else record)(name, mult, seed, v) for v in args.variants.split(",")]
                ):  # fmt: skip
                    rows.append(row)
                    print(json.dumps(row), flush=True)
                    if args.dump:
                        with open(args.dump, "a") as f:
                            f.write(json.dumps(row) + "\n")
    (spring_tables if args.spring else print_tables)(rows)


if __name__ == "__main__":
    main()
