"""Where a motor-side twin's play error comes from (issue 12): the encoder, the load's motion or the loop.

Run: ``.venv/bin/python benchmarks/motor_bias.py --presets cia402 --rates 10,50 --seeds 1,2,3
[--output-cpr 16384] [--effects "as is,load x0.01"] [--readings twin] [--held-load 0.89,10,0.85[,WC,ZETA,ALS,VLS[,TV]]]
[--contact-profile 566,400,283,200,141,100 [--contact-zeta 0.025] [--profile-modes "load free"]] [--tq-scales 0,1]
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
``;`` are each refitted from the same answer. ``--contact-profile WC,WC,...``: the answer refitted alike on the model's
compliant contact held at each frequency in turn (rad/s on the load's inertia, each from the fit before; damping ratio
``--contact-zeta``), with the load's inertia and friction held at the answer's and refitted too: the cost over the
contact's frequency as a fit of it would see it, and the play at its least (the twin's frequency is not given: a
user's gear has its own; :func:`contact_profile`). ``--tq-scales 0,0.5,1,2``: the model's torque lag (``tq``, s: the
drive's current loop between the velocity loop's command and the motor's torque) held at each multiple of the record's
twin's (:func:`twin_torque_lag_s`, from the twin's parameters as this run overrides them, so that a current loop made
faster or slower moves it along), in the contact profile (its points per multiple, and the rigid answer refitted with
the lag held, ``rigid``) and in each held load (a ninth value; 0: none, the load as given); ``--profile-tv TV`` holds
the model's velocity filter in the profile too (s). ``--effects`` are the twin's variants by the names of ``twin_effects.effects`` (one effect switched off or
scaled; a load of a hundredth, ``load x0.01``, leaves the motor side without the load it picks up at a flank).
Per effect and reading: within 5 %, mean, standard deviation, largest. The twins' presets are not changed (the
overrides make this run's copies). The machine may be shared: times are one run each.
"""

from __future__ import annotations

import argparse
import json
import math
import warnings
from typing import Any

import numpy as np
from _table import append_json, table
from play_at_truth import refit_setup
from real_servos import NOISE_COUNTS, run, twin_record
from scipy.optimize import minimize
from twin_effects import effects

from servoid.drivers.twin import preset
from servoid.ident.models.kernels import backlash_step
from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.load_stage import _PER_INERTIA
from servoid.ident.offline.operating_point import operating_point

#: The readings identify answers on (see the module's docstring).
READINGS = ("twin", "load now", "play operator")
#: What ``--held-load`` holds, in its order: the model's load, its contact (``wc`` 0: rigid), its break-away and its
#: velocity filter.
HELD_NAMES = ("mu", "al", "e", "wc", "zeta", "als", "vls", "tv", "tq")
#: ``--contact-profile``: the load's inertia and friction held at the answer's at every point, or refitted there.
PROFILE_MODES = ("load held", "load free")


def twin_torque_lag_s(params: Any) -> float:
    """The time constant of a cascade twin's current loop, s: ``L / kp`` (its PI's zero cancels the winding's pole,
    ``ki / kp = R / L``, so the loop is first order with the bandwidth ``kp / L``); 0 for a twin without one."""
    if params.firmware != "cascade" or params.inductance_h <= 0.0 or params.cur_kp_v_a <= 0.0:
        return 0.0
    return float(params.inductance_h / params.cur_kp_v_a)


def _lag_label(scale: float) -> str:
    """The key suffix of a profile held at ``scale`` times the twin's torque lag (none for 0)."""
    return "" if scale == 0.0 else f", tq x{scale:g}"


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


def _answer(
    u: np.ndarray, y: np.ndarray, period: float
) -> tuple[Any, tuple[np.ndarray, np.ndarray, float], dict[str, float], float]:
    """``fit_loop``'s answer as ``identify`` runs it (the record centred alike), what its refits need (the record as the
    final refit centres it, the scale of ``a0``), its values and its cost on every sample."""
    uc, yc = (np.asarray(a) for a in operating_point(u, y).centre(u, y))
    model = lf.fit_loop(uc, yc, period, load=None).model
    uc, yc, a_scale, _, answer = refit_setup(uc, yc, period, model)
    return model, (uc, yc, a_scale), answer, _cost(uc, yc, period, model, answer)


def _cost(uc: np.ndarray, yc: np.ndarray, period: float, model: Any, d: dict[str, float]) -> float:
    """The values ``d`` in ``model``'s structure: their sum of squared residuals on every sample."""
    return lf._cost(uc, yc, period, model.structure, d, np.ones(yc.size, dtype=bool))


def _refit(
    record: tuple[np.ndarray, np.ndarray, float],
    period: float,
    model: Any,
    start: dict[str, float],
    free: tuple[str, ...],
) -> tuple[dict[str, float], float]:
    """``start`` refitted on every sample with ``free`` free (the final refit's budget and stop): its values and cost."""
    uc, yc, a_scale = record
    d, _, _ = lf._fit(uc, yc, period, model.structure, start, np.ones(yc.size, dtype=bool), a_scale,
                      integrator=model.ki > 0.0, max_nfev=lf.FINAL_NFEV, free=free, ftol=lf.FTOL,
                      stall=lf.FINAL_STALL)  # fmt: skip
    return d, _cost(record[0], record[1], period, model, d)


def held_load(
    u: np.ndarray, y: np.ndarray, period: float, truth: float, loads: list[tuple[float, ...]]
) -> dict[str, Any]:
    """``fit_loop``'s answer (as ``identify`` runs it, the record centred alike) refitted on every sample with each load
    ``(mu, al, e[, wc, zeta[, als, vls[, tv]]])`` of ``loads`` held (:data:`HELD_NAMES`: the contact's frequency and
    damping, 0: rigid, the load's break-away and the velocity filter's time constant): the final refit's free parameters and budget, the per-inertia values started
    ``1 + mu`` times the massless ones. Returns the answer's play error and inertia ratio, and per load the held fit's
    play error and its cost in residual variances against the answer's."""
    model, rec, answer, base = _answer(u, y, period)
    plays, variances = [], []
    for load in loads:
        start = dict(answer, **dict(zip(HELD_NAMES, load, strict=False)))
        for name in _PER_INERTIA:
            start[name] = answer[name] * (1.0 + load[0]) / (1.0 + answer.get("mu", 0.0))
        d, cost = _refit(rec, period, model, start, lf._free(model.structure, model.ki > 0.0))
        plays.append(d["play"] / truth - 1.0)
        variances.append((cost - base) / (base / rec[1].size))
    return {"answer": model.play / truth - 1.0, "mu": float(model.mu), "held": plays, "variances": variances,
            "loads": [list(load) for load in loads]}  # fmt: skip


def contact_profile(
    u: np.ndarray,
    y: np.ndarray,
    period: float,
    truth: float,
    wcs: list[float],
    zeta: float,
    lags: tuple[list[float], float] = ([0.0], 0.0),
    modes: tuple[str, ...] = PROFILE_MODES,
    tv: float = 0.0,
) -> dict[str, Any]:
    """``fit_loop``'s answer (as ``identify`` runs it) refitted on every sample on the model's compliant contact held at
    each frequency of ``wcs`` (rad/s on the load's inertia, in the order given, each point started from the one before)
    with the damping ratio ``zeta``; the final refit's free parameters and budget, with the load's inertia and friction
    held at the answer's (:data:`PROFILE_MODES` "load held") or refitted too ("load free"). Returns the answer's play
    error and inertia ratio and per mode each point's ``[play error, cost in residual variances against the answer's,
    inertia ratio]``; nothing for a massless answer (the contact is a massive load's). ``lags``: the multiples of the
    twin's torque lag ``tq`` (s) the profile is run at (each a mode of its own, ``"load free, tq x1"``: the lag held at
    every point, and ``"rigid, tq x1"``: the answer refitted with the lag alone); ``modes``: which of
    :data:`PROFILE_MODES`; ``tv``: the model's velocity filter held at every point too, s (0: none)."""
    model, rec, answer, base = _answer(u, y, period)
    scales, tq_twin = lags
    row: dict[str, Any] = {"answer": model.play / truth - 1.0, "mu": float(model.mu), "wcs": wcs, "zeta": zeta,
                           "samples": int(rec[1].size), "tq": tq_twin}  # fmt: skip
    if not model.massive:
        return row
    loop = lf._free(model.structure, model.ki > 0.0)
    for scale in scales:
        start = dict(answer, tq=scale * tq_twin, **({"tv": tv} if tv > 0.0 else {}))
        if scale > 0.0:
            d, cost = _refit(rec, period, model, start, loop)
            row["rigid" + _lag_label(scale)] = [d["play"] / truth - 1.0, (cost - base) / (base / rec[1].size), d["mu"]]
        for mode, free in zip(PROFILE_MODES, (loop, loop + ("mu", "al")), strict=True):
            if mode not in modes:
                continue
            d, points = start, []
            for wc in wcs:
                d, cost = _refit(rec, period, model, dict(d, wc=wc, zeta=zeta), free)
                points.append([d["play"] / truth - 1.0, (cost - base) / (base / rec[1].size), d["mu"]])
            row[mode + _lag_label(scale)] = points
    return row


def profile_modes(row: dict[str, Any]) -> list[str]:
    """The contact profile's modes in ``row`` (:data:`PROFILE_MODES`, each with and without a torque lag)."""
    return [k for k in row if k.startswith(PROFILE_MODES)]


def least(row: dict[str, Any], mode: str, pays: bool = False) -> tuple[float, float]:
    """A contact profile's point of least cost (:func:`contact_profile`): its frequency and play error; with ``pays``,
    only where it costs more than ``ln n`` residual variances less than the answer (BIC, the one parameter ``wc``).
    Elsewhere (and for a massless answer) the answer's play error, at the frequency 0 (rigid)."""
    if mode not in row:
        return 0.0, row["answer"]
    at = int(np.argmin([p[1] for p in row[mode]]))
    if pays and not row[mode][at][1] < -math.log(row["samples"]):
        return 0.0, row["answer"]
    return row["wcs"][at], row[mode][at][0]


def record(
    name: str,
    what: str,
    over: dict[str, object],
    mult: float,
    seed: int,
    wanted: tuple[str, ...] = READINGS,
    held: list[tuple[float, ...]] | None = None,
    profile: tuple[list[float], float] | None = None,
    tq_scales: list[float] | None = None,
    modes: tuple[str, ...] = PROFILE_MODES,
    tv: float = 0.0,
) -> dict[str, Any]:
    """One record's play errors on the ``wanted`` readings, and the load's against the gear's motor side (``tq_scales``:
    the held loads and the contact profile at those multiples of the twin's torque lag, :func:`twin_torque_lag_s`)."""
    rec = twin_record(name, mult, 1.0, "sines", seed, **over)
    tq_twin = twin_torque_lag_s(preset(name, **over))  # type: ignore[arg-type]
    if tq_scales and held:
        held = [load + (0.0,) * (8 - len(load)) + (s * tq_twin,) for s in tq_scales for load in held]
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
    row["tq twin"] = tq_twin
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
    if profile:
        row["contact profile"] = contact_profile(
            np.asarray(rec["u"]), readings["twin"], period, truth, *profile, (tq_scales or [0.0], tq_twin), modes, tv
        )
    return row


def _held(row: dict[str, Any]) -> tuple[list[float], list[float]]:
    """A row's held fits' play errors and costs (one load in dumps written before ``--held-load`` took several)."""
    held = row["held load"]
    return list(np.atleast_1d(held["held"])), list(np.atleast_1d(held["variances"]))


def _profiled(row: dict[str, Any], mode: str) -> str:
    """A row's contact profile in ``mode``: the answer's play error, each point's, and the least cost's frequency."""
    if "contact profile" not in row:
        return ""
    prof = row["contact profile"]
    if mode not in prof:
        return f"{100 * prof['answer']:+.1f} % (massless)"
    points = " / ".join(f"{100 * p[0]:+.1f} ({p[1]:+.0f})" for p in prof[mode])
    rigid = prof.get("rigid" + mode[mode.index(", tq") :]) if ", tq" in mode else None
    head = f"{100 * prof['answer']:+.1f}" + (f", rigid {100 * rigid[0]:+.1f} ({rigid[1]:+.0f})" if rigid else "")
    return f"{head} -> {points}: {least(prof, mode)[0]:g}"


def print_tables(rows: list[dict[str, Any]]) -> None:
    """The per-record table and the summary per effect and reading."""
    modes = list(dict.fromkeys(m for r in rows if "contact profile" in r for m in profile_modes(r["contact profile"])))
    modes = modes or list(PROFILE_MODES)
    table(
        "identify's play error on each reading (mu: the load stage's inertia ratio, 0 massless)",
        ["preset", "effect", "rate", "seed", "play (counts)", *READINGS, "load vs gear", "held load (variances)",
         *(f"contact, {mode}: least (rad/s)" for mode in modes)],
        [[r["preset"], r["effect"], f"{r['mult']:g}x", str(r["seed"]), f"{r['counts']:.2f}",
          *(f"{100 * r[k]['gap']:+.1f} % ({r[k]['mu']:.2f})" if k in r else "" for k in READINGS),
          f"{100 * r['load vs gear']:+.2f} %",
          f"{100 * r['held load']['answer']:+.1f} -> " + " / ".join(
              f"{100 * g:+.1f} % ({v:+.0f})" for g, v in zip(*_held(r), strict=True)) if "held load" in r else "",
          *(_profiled(r, mode) for mode in modes)]
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
        where: dict[str, str] = {}
        if "contact profile" in group[0]:
            columns["contact profile: answer"] = [r["contact profile"]["answer"] for r in group]
            for rigid in (k for k in group[0]["contact profile"] if k.startswith("rigid")):
                columns[f"contact profile: {rigid}"] = [r["contact profile"].get(rigid, [r["contact profile"]["answer"]])[0]
                                                        for r in group]  # fmt: skip
            for mode in modes:
                columns[f"contact profile, {mode}: least"] = [least(r["contact profile"], mode)[1] for r in group]
                where[f"contact profile, {mode}: least"] = _where(group, mode)
                columns[f"contact profile, {mode}: where it pays"] = [
                    least(r["contact profile"], mode, pays=True)[1] for r in group
                ]
        for reading, gaps in columns.items():
            g = np.array(gaps)
            out.append([*key, reading, str(g.size), str(int(np.sum(np.abs(g) <= 0.05))), f"{100 * g.mean():+.1f} %",
                        f"{100 * g.std(ddof=1) if g.size > 1 else 0.0:.1f} %", f"{100 * np.abs(g).max():.1f} %",
                        where.get(reading, "")])  # fmt: skip
    table(
        "Per effect and reading (least: where the profile's least cost sits, rad/s; heavy: the answers with mu > 2)",
        ["preset", "effect", "reading", "records", "within 5 %", "mean", "sd", "largest", "least at"],
        out,
    )


def _where(group: list[dict[str, Any]], mode: str) -> str:
    """Where a profile's least cost sits on a group's records, and on its heavy answers (``mu > 2``): ``200 on 9``."""

    def counted(rows: list[dict[str, Any]]) -> str:
        at = [least(r["contact profile"], mode)[0] for r in rows]
        return ", ".join(f"{wc:g} on {at.count(wc)}" for wc in sorted(set(at), reverse=True))

    heavy = [r for r in group if r["contact profile"]["mu"] > 2.0]
    return f"{counted(group)}; heavy {len(heavy)}: {counted(heavy)}"


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
    profile_help = "WC,WC,... rad/s, in this order: also refit the answer on the contact held at each (contact_profile)"
    parser.add_argument("--contact-profile", default="", help=profile_help)
    parser.add_argument("--contact-zeta", type=float, default=0.025, help="the profile's contact damping ratio")
    parser.add_argument(
        "--profile-modes", default=",".join(PROFILE_MODES), help="comma-separated: " + ", ".join(PROFILE_MODES)
    )
    parser.add_argument("--profile-tv", type=float, default=0.0, help="the profile's velocity filter held, s (0: none)")
    parser.add_argument(
        "--tq-scales", default="", help="S,S,...: the model's torque lag held at S x the twin's (0: none)"
    )
    parser.add_argument("--dump", default=None)
    parser.add_argument("--load", default=None)
    args = parser.parse_args()
    if args.load:
        with open(args.load) as f:
            print_tables([json.loads(line) for line in f])
        return
    held = [tuple(float(v) for v in load.split(",")) for load in args.held_load.split(";") if load.strip()]
    wcs = [float(v) for v in args.contact_profile.split(",") if v.strip()]
    profile = (wcs, args.contact_zeta) if wcs else None
    tq_scales = [float(v) for v in args.tq_scales.split(",") if v.strip()] or None
    modes = tuple(m.strip() for m in args.profile_modes.split(",") if m.strip())
    if any(m not in PROFILE_MODES for m in modes):
        raise SystemExit(f"--profile-modes (={args.profile_modes!r}) must name {' or '.join(PROFILE_MODES)}")
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
                    rows.append(
                        record(name, what, over, mult, seed, wanted, held, profile, tq_scales, modes, args.profile_tv)
                    )
                    print(json.dumps(rows[-1]), flush=True)
                    append_json(args.dump, rows[-1])
    print_tables(rows)


if __name__ == "__main__":
    main()
