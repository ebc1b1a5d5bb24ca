"""Where a motor-side twin's play error comes from (issue 12): the encoder, the load's motion or the loop.

Run: ``.venv/bin/python benchmarks/motor_bias.py --presets cia402 --rates 10,50 --seeds 1,2,3
[--output-cpr 16384] [--effects "as is,load x0.01"] [--readings twin] [--held-load 0.89,10,0.85[,WC,ZETA,ALS,VLS[,TV]]]
[--dump out.jsonl]``; ``--load out.jsonl`` prints a dump's tables again.

On each record (``real_servos.twin_record``: the table's gentle sines and 0.3 count of noise; the output encoder's
counts per revolution ``--output-cpr``, default the table's 4096), ``identify`` with no flags on three readings of
the same run:

- ``twin``: the output encoder's reading as the twin records it (the table's: the drive's latest tick);
- ``load now``: the true load angle at the host instant, read by the encoder's law
  (``floor(theta / q + 1/2 + n)``, ``n`` 0.3 count, another draw): the reading's age taken out;
- ``play operator``: the massless play operator of the model (the true play, centred) applied to the true motor
  side of the gear (``theta_m / N``) at the host instants, read alike: the load's own motion (its coasting, bounce
  and windup) taken out. What is left of the play error is the loop's: the model's motor against the twin's.

And, without a fit of the loop, ``load vs gear``: the play of the play operator of the true gear side fitted to
the true load by least squares (the play the load's own motion shows against the motor; 0 is the truth).
``--held-load MU,AL,E``: also ``fit_loop``'s answer on the twin's reading (as ``identify`` runs it) refitted on
every sample with the model's load (:mod:`~servoid.ident.offline.load_stage`: inertia ratio, friction as a
deceleration, restitution) held at those values (the CiA 402 twin's: ``0.89,10,0.85``): whether the model's own load
term, given the truth, takes the bias off. ``--held-load MU,AL,E,WC,ZETA[,ALS,VLS]`` holds the model's compliant
contact too (``wc`` its frequency on the load's inertia, rad/s, 0: rigid; ``zeta`` its damping ratio) and the load's
break-away (``als`` its static friction as a deceleration, ``vls`` its Stribeck speed; the CiA 402 twin's:
``0.89,10,0.85,1944.6,0.036,12.5,0.01``, from its gear's 75 630 N m/rad and 2.8 N m s on 0.02 kg m^2, and the load's
0.25 N m break-away over 0.01 rad/s; the ODrive's ``2.84,2.5,0.92,200,0.025,3,0.01``), and an eighth value holds
the model's velocity filter (``tv``, s: the time constant on the speed its velocity loop feeds back; the CiA 402
drive's 0.001; ``0,0,0,0,0,0,0,0.001`` is the massless answer with the filter alone). Several loads separated by
``;`` are each refitted from the same answer. ``--effects`` are the twin's variants by the names of ``twin_effects.effects`` (one effect switched off or
scaled; a load of a hundredth, ``load x0.01``, leaves the motor side without the load it picks up at a flank).
Per effect and reading: within 5 %, mean, standard deviation, largest. The twins' presets are not changed (the
overrides make this run's copies). The machine may be shared: times are one run each.
"""

from __future__ import annotations

import argparse
import json
import warnings
from typing import Any

import numpy as np
from _table import append_json, table
from play_at_truth import refit_setup
from real_servos import NOISE_COUNTS, run, twin_record
from scipy.optimize import minimize
from twin_effects import effects

from servoid.ident.models.kernels import backlash_step
from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.load_stage import _PER_INERTIA
from servoid.ident.offline.operating_point import operating_point

#: The readings identify answers on (see the module's docstring).
READINGS = ("twin", "load now", "play operator")
#: What ``--held-load`` holds, in its order: the model's load, its contact (``wc`` 0: rigid), its break-away and its
#: velocity filter.
HELD_NAMES = ("mu", "al", "e", "wc", "zeta", "als", "vls", "tv")


def play_operator(x: np.ndarray, play: float, y0: float) -> np.ndarray:
    """The massless play of ``play`` (centred: half each side) driven by ``x``, starting at ``y0``."""
    y = np.empty_like(x)
    y_prev, x_prev = y0, x[0]
    for k, xk in enumerate(x):
        y_prev, _ = backlash_step(float(xk), float(x_prev), y_prev, 1.0, 0.5 * play, 0.5 * play)
        x_prev = xk
        y[k] = y_prev
    return y


def encoder_read(theta: np.ndarray, cpr: float, rng: np.random.Generator) -> np.ndarray:
    """``theta`` read by an encoder of ``cpr`` counts per revolution with the table's noise, rad."""
    q = 2.0 * np.pi / cpr
    return q * np.floor(theta / q + 0.5 + NOISE_COUNTS * rng.standard_normal(theta.size))


def load_vs_gear(gear: np.ndarray, load: np.ndarray, play: float) -> float:
    """The play (over the truth, less 1) of the play operator of ``gear`` that fits ``load`` best, centre free."""

    def cost(p: np.ndarray) -> float:
        shifted = play_operator(gear - p[1] * play, p[0] * play, load[0])
        return float(np.mean((shifted - load) ** 2))

    found = minimize(cost, np.array([1.0, 0.0]), method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 0.0})
    return float(found.x[0]) - 1.0


def held_load(
    u: np.ndarray, y: np.ndarray, period: float, truth: float, loads: list[tuple[float, ...]]
) -> dict[str, Any]:
    """``fit_loop``'s answer (as ``identify`` runs it, the record centred alike) refitted on every sample with each load
    ``(mu, al, e[, wc, zeta[, als, vls[, tv]]])`` of ``loads`` held (:data:`HELD_NAMES`: the contact's frequency and
    damping, 0: rigid, the load's break-away and the velocity filter's time constant): the final refit's free parameters and budget, the per-inertia values started
    ``1 + mu`` times the massless ones. Returns the answer's play error and inertia ratio, and per load the held fit's
    play error and its cost in residual variances against the answer's."""
    uc, yc = (np.asarray(a) for a in operating_point(u, y).centre(u, y))
    model = lf.fit_loop(uc, yc, period, load=None).model
    uc, yc, a_scale, _, answer = refit_setup(uc, yc, period, model)
    every = np.ones(yc.size, dtype=bool)
    base = lf._cost(uc, yc, period, model.structure, answer, every)
    plays, variances = [], []
    for load in loads:
        start = dict(answer, **dict(zip(HELD_NAMES, load, strict=False)))
        for name in _PER_INERTIA:
            start[name] = answer[name] * (1.0 + load[0]) / (1.0 + answer.get("mu", 0.0))
        d, _, _ = lf._fit(uc, yc, period, model.structure, start, every, a_scale, integrator=model.ki > 0.0,
                          max_nfev=lf.FINAL_NFEV, free=lf._free(model.structure, model.ki > 0.0), ftol=lf.FTOL,
                          stall=lf.FINAL_STALL)  # fmt: skip
        cost = lf._cost(uc, yc, period, model.structure, d, every)
        plays.append(d["play"] / truth - 1.0)
        variances.append((cost - base) / (base / yc.size))
    return {"answer": model.play / truth - 1.0, "mu": float(model.mu), "held": plays, "variances": variances,
            "loads": [list(load) for load in loads]}  # fmt: skip


def record(
    name: str,
    what: str,
    over: dict[str, object],
    mult: float,
    seed: int,
    wanted: tuple[str, ...] = READINGS,
    held: list[tuple[float, ...]] | None = None,
) -> dict[str, Any]:
    """One record's play errors on the ``wanted`` readings, and the load's against the gear's motor side."""
    rec = twin_record(name, mult, 1.0, "sines", seed, **over)
    truth, period, cpr = float(rec["play"]), float(rec["period"]), float(rec["cpr"])  # type: ignore[arg-type]
    gear, load = np.asarray(rec["gear_side_true"]), np.asarray(rec["load_true"])
    rng = np.random.default_rng(seed + 77)
    readings = {
        "twin": np.asarray(rec["y"]),
        "load now": encoder_read(load, cpr, rng),
        "play operator": encoder_read(play_operator(gear, truth, load[0]), cpr, np.random.default_rng(seed + 78)),
    }
    row: dict[str, Any] = {
        "preset": name,
        "effect": what,
        "mult": mult,
        "seed": seed,
        "counts": truth * cpr / (2 * np.pi),
    }
    for label in wanted:
        y = readings[label]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result, seconds = run(np.asarray(rec["u"]), y, period)
        row[label] = {"gap": result.play / truth - 1.0, "mu": float(result.loop.model.mu) if result.loop else 0.0,
                      "s": seconds}  # fmt: skip
    row["load vs gear"] = load_vs_gear(gear, load, truth)
    if held:
        row["held load"] = held_load(np.asarray(rec["u"]), readings["twin"], period, truth, held)
    return row


def _held(row: dict[str, Any]) -> tuple[list[float], list[float]]:
    """A row's held fits' play errors and costs (one load in dumps written before ``--held-load`` took several)."""
    held = row["held load"]
    return list(np.atleast_1d(held["held"])), list(np.atleast_1d(held["variances"]))


def print_tables(rows: list[dict[str, Any]]) -> None:
    """The per-record table and the summary per effect and reading."""
    table(
        "identify's play error on each reading (mu: the load stage's inertia ratio, 0 massless)",
        ["preset", "effect", "rate", "seed", "play (counts)", *READINGS, "load vs gear", "held load (variances)"],
        [[r["preset"], r["effect"], f"{r['mult']:g}x", str(r["seed"]), f"{r['counts']:.2f}",
          *(f"{100 * r[k]['gap']:+.1f} % ({r[k]['mu']:.2f})" if k in r else "" for k in READINGS),
          f"{100 * r['load vs gear']:+.2f} %",
          f"{100 * r['held load']['answer']:+.1f} -> " + " / ".join(
              f"{100 * g:+.1f} % ({v:+.0f})" for g, v in zip(*_held(r), strict=True)) if "held load" in r else ""]
         for r in rows],
    )  # fmt: skip
    out = []
    for key in dict.fromkeys((r["preset"], r["effect"]) for r in rows):
        group = [r for r in rows if (r["preset"], r["effect"]) == key]
        columns = {k: [r[k]["gap"] for r in group] for k in READINGS if k in group[0]}
        columns["load vs gear"] = [r["load vs gear"] for r in group]
        if "held load" in group[0]:
            columns["held load: answer"] = [r["held load"]["answer"] for r in group]
            for i, load in enumerate(group[0]["held load"].get("loads", [[]])):
                columns[f"held load {','.join(f'{v:g}' for v in load)}"] = [_held(r)[0][i] for r in group]
        for reading, gaps in columns.items():
            g = np.array(gaps)
            out.append([*key, reading, str(g.size), str(int(np.sum(np.abs(g) <= 0.05))), f"{100 * g.mean():+.1f} %",
                        f"{100 * g.std(ddof=1) if g.size > 1 else 0.0:.1f} %", f"{100 * np.abs(g).max():.1f} %"])  # fmt: skip
    table(
        "Per effect and reading", ["preset", "effect", "reading", "records", "within 5 %", "mean", "sd", "largest"], out
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="cia402")
    parser.add_argument("--rates", default="10,50")
    parser.add_argument("--seeds", default="1,2,3")
    parser.add_argument("--effects", default="as is", help="comma-separated names of twin_effects.effects")
    parser.add_argument("--output-cpr", type=int, default=0, help="output encoder counts per revolution (default 4096)")
    parser.add_argument("--readings", default=",".join(READINGS), help="comma-separated: " + ", ".join(READINGS))
    parser.add_argument(
        "--held-load",
        default="",
        help="MU,AL,E[,WC,ZETA[,ALS,VLS[,TV]]], several separated by ';': also refit the twin reading's answer with each load "
        "held (see held_load)",
    )
    parser.add_argument("--dump", default=None)
    parser.add_argument("--load", default=None)
    args = parser.parse_args()
    if args.load:
        with open(args.load) as f:
            print_tables([json.loads(line) for line in f])
        return
    held = [tuple(float(v) for v in load.split(",")) for load in args.held_load.split(";") if load.strip()]
    rows = []
    for name in args.presets.split(","):
        cases = effects(name)
        for what in (e.strip() for e in args.effects.split(",")):
            if what not in cases:
                raise SystemExit(f"effect (={what!r}) must be one of {', '.join(cases)}")
            over = {**cases[what], **({"load_encoder_cpr": args.output_cpr} if args.output_cpr else {})}
            for mult in (float(m) for m in args.rates.split(",")):
                for seed in (int(s) for s in args.seeds.split(",")):
                    wanted = tuple(r for r in args.readings.split(",") if r)
                    rows.append(record(name, what, over, mult, seed, wanted, held))
                    print(json.dumps(rows[-1]), flush=True)
                    append_json(args.dump, rows[-1])
    print_tables(rows)


if __name__ == "__main__":
    main()
