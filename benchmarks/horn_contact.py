"""A light horn on a compliant gear contact, fitted by least squares where the flank rebound is named.

Run: ``.venv/bin/python benchmarks/horn_contact.py [--records sts3215:20:1,xm430:50:1,sts3215:10:1:10]
[--chaos sts3215:20:1] [--own sts3215:20:1] [--all]``; a record is ``preset:rate:seed[:gear damping factor]``
(gentle sines, ``real_servos.py``'s).

The measurement behind :mod:`servoid.ident.offline.horn_contact` (issue 12, hornstage session), with
its constants; ``identify`` runs the two-stage path only. The rigid-impact horn of
``horn_stage.py`` makes the free run chaotic (0.1 % of play moves it 0.26 counts rms); the
model's compliant contact (:func:`~servoid.ident.models.servo_loop._advance_contact`, on its own
sub-step) does not (``--chaos``: 0.016 counts at the twins' contact, 775 rad/s and a damping
ratio of 0.078, less than the massless model's 0.125), so the fit's own difference step
(:data:`~servoid.ident.offline.loop_fit.DIFF_STEP`, 3 % in log coordinates) sees a slope and
least squares can move the contact's frequency ``wc`` and damping ratio ``zeta`` with the rest.

The stage (:func:`contact_stage`), on the search's window from the best play-in-loop candidate of
:func:`~servoid.ident.offline.loop_fit.fit_loop`, the horn's inertia ratio held at
:data:`MU` and the contact started at :data:`WC_START`, :data:`ZETA_START`:
``direct``: everything free at once; ``two-stage``: first the play and the horn (``al``, ``wc``,
``zeta``) with the loop held, then everything. Then the kept one (two-stage) refitted on the
whole record. Printed per record: fit_loop's answer (the massless model; identify reaches fit_loop
through its own record handling, so its answer can differ) and its fit over the floor, whether :func:`~servoid.ident.diagnosis.flank_rebound.rebound` names the bounce on it, both
paths' play, their cost on the window's estimation blocks (over the massless candidate's) and
validation (over the twin's floor), the contact found, the whole-record refit's play and fit, and
the time. ``--own``: the two paths on the model's own simulation (the first record's massless loop
with a horn of 0.026 and 20 rad/s^2 on a 775 rad/s / 0.078 contact), noise-free and with 4096
counts and 0.3 count of noise. The measured numbers are in the README ("What we learned", "A
compliant horn is not chaotic"): on the STS3215's nine rows (10/20/50x, seeds 1-3) the whole-record
answer is -10.2 ... +5.6 % at 1.04-1.21x the floor, where fit_loop's massless one is -18.6 ... -5.7 %.
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import replace

import numpy as np
from _table import table
from horn_stage import clean_and_read, massless, moved_by
from real_servos import twin_record

from servoid.drivers.twin import preset
from servoid.ident.diagnosis.flank_rebound import rebound
from servoid.ident.metrics import free_run_nrmse, nrmse
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.horn_contact import AL_START, HORN, MU, NFEV, WC_START, ZETA_START

#: The model's own simulation: the horn (inertia ratio, friction rad/s^2) and its contact (rad/s, damping ratio).
OWN_HORN, OWN_CONTACT = (0.026, 20.0), (775.0, 0.078)


def _record(spec: str) -> dict[str, object]:
    name, mult, seed, *damping = spec.split(":")
    over = {"gear_damping_nms": float(damping[0]) * preset(name).gear_damping_nms} if damping else {}
    return twin_record(name, float(mult), 1.0, "sines", int(seed), **over)


def contact_stage(
    uc: np.ndarray, yc: np.ndarray, period: float, start: ServoLoopModel, integrator: bool
) -> dict[str, tuple[dict[str, float], float, float, int, float]]:
    """Both paths (module docstring) on centred signals: per path the values, estimation SSE, validation NRMSE,
    simulations and seconds."""
    _, kv = lf._linear_start(uc, yc, period)
    v_typ = float(np.std(np.diff(yc))) / period
    a_scale = 0.1 * kv * v_typ
    est = lf.block_mask(yc.size)
    d0 = {k: float(v) for k, v in start.params().items()}
    d0.update(play=start.play, asym=(start.c1 - start.c2) / (2.0 * start.play) if start.play > 0.0 else 0.0)
    s = dict(d0, mu=MU, e=0.0, al=AL_START * d0["fc"], wc=WC_START, zeta=ZETA_START)
    if s["fs"] <= s["fc"]:  # the searches lose the hump (loop_fit._final_fit): restart from one
        s.update(fs=lf.HUMP_RESTART * s["fc"], vs=max(s["vs"], lf.HUMP_VS * v_typ))
    loop = lf._free(PLAY_IN_LOOP, integrator)

    def fit(begin: dict[str, float], free: tuple[str, ...]) -> tuple[dict[str, float], int]:
        d, prob, _ = lf._fit(uc, yc, period, PLAY_IN_LOOP, begin, est, a_scale, integrator=integrator,
                             max_nfev=NFEV, free=free)  # fmt: skip
        return d, prob.evaluations

    out = {}
    for path in ("direct", "two-stage"):
        started = time.perf_counter()
        sims = 0
        begin = s
        if path == "two-stage":
            begin, sims = fit(s, ("play", *HORN))
        d, used = fit(begin, loop + HORN)
        sim = lf._model(PLAY_IN_LOOP, period, d).simulate(uc, y0=float(yc[0]))
        r = sim[est] - yc[est]
        out[path] = (d, float(r @ r), free_run_nrmse(yc[~est], sim[~est]), sims + used, time.perf_counter() - started)
    return out


def _whole(
    u: np.ndarray, y: np.ndarray, period: float, d: dict[str, float], integrator: bool
) -> tuple[dict[str, float], float]:
    """The two-stage answer refitted on every sample (the final refit's budget); its values and fit NRMSE."""
    centre = float(np.mean(u))
    uc, yc = u - centre, y - centre
    _, kv = lf._linear_start(uc, yc, period)
    a_scale = 0.1 * kv * float(np.std(np.diff(yc))) / period
    free = lf._free(PLAY_IN_LOOP, integrator) + HORN
    whole, _, _ = lf._fit(uc, yc, period, PLAY_IN_LOOP, d, np.ones(yc.size, bool), a_scale, integrator=integrator,
                          max_nfev=lf.FINAL_NFEV, free=free)  # fmt: skip
    return whole, nrmse(yc, lf._model(PLAY_IN_LOOP, period, whole).simulate(uc, y0=float(yc[0])))


def records(specs: list[str]) -> None:
    """Per record: fit_loop's answer, the rebound, both paths and the whole-record refit (module docstring)."""
    rows = []
    for spec in specs:
        rec = _record(spec)
        u, y, period = np.asarray(rec["u"]), np.asarray(rec["y"]), float(rec["period"])  # type: ignore[arg-type]
        play, floor = float(rec["play"]), float(rec["floor"])  # type: ignore[arg-type]
        started = time.perf_counter()
        choice = lf.fit_loop(u, y, period, load=None)
        t_loop = time.perf_counter() - started
        named = "-"
        if choice.structure == PLAY_IN_LOOP:
            named = "named" if rebound(y, np.asarray(choice.simulated), choice.play, period).named else "not"
        cand = min((c for c in choice.candidates if c.structure == PLAY_IN_LOOP), key=lambda c: c.validation_nrmse)
        w = lf.SEARCH_SAMPLES if u.size >= 2 * lf.SEARCH_SAMPLES else u.size
        centre = float(np.mean(u))
        uc, yc = u[:w] - centre, y[:w] - centre
        est = lf.block_mask(yc.size)
        r0 = cand.model.simulate(uc, y0=float(yc[0]))[est] - yc[est]
        paths = contact_stage(uc, yc, period, cand.model, cand.integrator)
        started = time.perf_counter()
        whole, fit = _whole(u, y, period, paths["two-stage"][0], cand.integrator)
        t_whole = time.perf_counter() - started

        def gap(p: float, truth: float = play) -> str:
            return f"{100 * (p / truth - 1):+.1f} %"

        row = [spec, gap(choice.play), f"{choice.fit_nrmse / floor:.3f}", choice.structure.replace("_", " "), named,
               gap(cand.model.play),
               f"{cand.validation_nrmse / floor:.3f}"]  # fmt: skip
        for path in ("direct", "two-stage"):
            d, cost, val, sims, secs = paths[path]
            row += [gap(d["play"]), f"{cost / float(r0 @ r0):.3f}", f"{val / floor:.3f}",
                    f"{d['wc']:.0f} / {d['zeta']:.3f}", f"{sims} {secs:.1f}"]  # fmt: skip
        row += [gap(whole["play"]), f"{fit / floor:.3f}", f"{t_loop:.1f}", f"{t_whole:.1f}"]
        rows.append(row)
        print(" | ".join(row), flush=True)
    table(
        "A light horn (mu held at 0.03) on a compliant contact, least squares from the best play-in-loop candidate "
        "(gap = play / the twin's - 1; est = SSE on the window's estimation blocks / the massless candidate's; "
        "val / floor; the whole-record refit from the two-stage answer; fit: on every sample / floor)",
        ["record", "fit_loop", "fit", "place", "rebound", "massless cand", "val", "direct", "est", "val", "wc / zeta",
         "sims s", "two-stage", "est", "val", "wc / zeta", "sims s", "whole", "fit", "fit_loop s", "whole s"],
        rows,
    )  # fmt: skip


def chaos(spec: str) -> None:
    """How far 0.1 % of one parameter moves the free run: massless, rigid impacts, compliant contacts."""
    rec = _record(spec)
    u, period, play = np.asarray(rec["u"]), float(rec["period"]), float(rec["play"])  # type: ignore[arg-type]
    start, *_ = massless(u, np.asarray(rec["y"]), period)
    base = replace(start, c1=play / 2, c2=play / 2)
    rigid = replace(base, mu=OWN_HORN[0], al=OWN_HORN[1], e=0.78)
    models = [("massless", base), ("rigid, e 0.78", rigid)]
    models += [(f"contact {wc:g} / {z:g}", replace(rigid, e=0.0, wc=wc, zeta=z))
               for wc in (775.0, 300.0) for z in (0.078, 0.2, 0.5)]  # fmt: skip
    uc = u - float(np.mean(u))
    q = 2.0 * np.pi / 4096
    rows = []
    for label, model in models:
        started = time.perf_counter()
        y0 = model.simulate(uc, y0=0.0)
        secs = time.perf_counter() - started
        for pname in ("play", "al", "fc") if model.massive else ("play", "fc"):
            rms, peak = moved_by(model, pname, uc, y0)
            rows.append([label, pname, f"{rms / q:.3f}", f"{peak / q:.2f}", f"{1e3 * secs:.1f}"])
    table(
        f"The free run's sensitivity ({spec} play-in-loop candidate's loop, the twin's play, horn mu {OWN_HORN[0]}, "
        f"al {OWN_HORN[1]}): one parameter x 1.001",
        ["load", "parameter", "counts rms", "counts peak", "ms a run"],
        rows,
    )


def own(spec: str) -> None:
    """Both paths on the model's own simulation with a horn on a compliant contact (module docstring)."""
    rec = _record(spec)
    u, period, play = np.asarray(rec["u"]), float(rec["period"]), float(rec["play"])  # type: ignore[arg-type]
    start, *_ = massless(u, np.asarray(rec["y"]), period)
    truth = replace(start, c1=play / 2, c2=play / 2, mu=OWN_HORN[0], al=OWN_HORN[1],
                    wc=OWN_CONTACT[0], zeta=OWN_CONTACT[1])  # fmt: skip
    uc = u - float(np.mean(u))
    rows = []
    for label, y in clean_and_read(truth.simulate(uc, y0=0.0), int(spec.split(":")[2])):
        cand, integrator, _ = massless(uc, y, period)
        paths = contact_stage(uc, y, period, cand, integrator)
        row = [label, f"{100 * (cand.play / play - 1):+.1f} %"]
        for path in ("direct", "two-stage"):
            d, cost, val, sims, secs = paths[path]
            row += [f"{100 * (d['play'] / play - 1):+.1f} %", f"{cost:.3g}", f"{val:.3g}",
                    f"{d['wc']:.0f} / {d['zeta']:.3f}", f"{sims} {secs:.1f}"]  # fmt: skip
        rows.append(row)
    table(
        f"The model's own simulation ({spec} candidate's loop, a horn mu {OWN_HORN[0]}, al {OWN_HORN[1]} on "
        f"{OWN_CONTACT[0]:g} rad/s / {OWN_CONTACT[1]:g}; estimation SSE rad^2, validation NRMSE)",
        ["record", "massless", "direct", "SSE", "val", "wc / zeta", "sims s", "two-stage", "SSE", "val", "wc / zeta",
         "sims s"],
        rows,
    )  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", default="sts3215:20:1,sts3215:20:2,xm430:50:1", help="preset:rate:seed[:damping x]")
    ap.add_argument(
        "--all", action="store_true", help="STS3215 and XM430 10/20/50x s1-2, both damped x10 at 10x, STS3215 s3"
    )
    ap.add_argument("--chaos", default=None, help="first the free run's sensitivity on this record")
    ap.add_argument("--own", default=None, help="first both paths on the model's own simulation on this record's loop")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    lf._LOG_LIMITS["mu"] = (1e-3, 10.0)  # this process only: light horns
    lf._LOG = frozenset(lf._LOG | {"wc", "zeta"})  # and the contact in log coordinates
    if args.chaos:
        chaos(args.chaos)
    if args.own:
        own(args.own)
    specs = args.records.split(",")
    if args.all:
        specs = [f"{n}:{r}:{s}" for n in ("sts3215", "xm430") for r in (10, 20, 50) for s in (1, 2)]
        specs += [f"{n}:10:{s}:10" for n in ("sts3215", "xm430") for s in (1, 2)]
        specs += [f"sts3215:{r}:3" for r in (10, 20, 50)]
    records(specs)


if __name__ == "__main__":
    main()
