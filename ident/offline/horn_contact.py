"""A light horn on a compliant gear contact, fitted where the flank rebound is named (issue 12).

Where the encoder sits on the horn (the play in the loop) and the horn bounces off the flank the
motor hits (:func:`~servoid.ident.diagnosis.flank_rebound.rebound` names it), the massless model
books the bounce as less play (the STS3215 twin: -6 ... -19 %). This stage gives the winner a
horn of its own inertia (the ratio held at :data:`MU`) on the model's compliant contact
(:func:`~servoid.ident.models.servo_loop._advance_contact`: natural frequency ``wc``, damping
ratio ``zeta``, the horn's friction ``al``), fitted in two stages on the search's window from the
best play-in-loop candidate: first the play and the horn with the loop held, then everything;
then refitted on every sample, then profiled over the play on every sample (:data:`PLAY_PROFILE`: the play held
on a grid about its own, the rest refitted; where a point costs less, the refit on every sample starts from it).
Unlike rigid impacts, the contact's free run is smooth in its
parameters (0.1 % of play moves it 0.016 counts rms against 0.255), so least squares with the
fit's own difference step reaches the play: on the model's own simulation +3.0 % noise-free and
-3.4 % with 4096 counts and noise (everything free at once from the massless fit: +13.8 / +10.9
%). README, "What we learned", "A compliant horn is not chaotic"; ``benchmarks/horn_contact.py``.

Kept where it validates :data:`~servoid.ident.offline.loop_fit.LOAD_MARGIN` better than the
massless candidate on the window's validation blocks; the kept answer carries a doubt
(:data:`REASON`: its interval is not calibrated on horn servos) and an interval that holds the
massless play too, and its mirror about the horn's play: the correction is taken as uncertain as it
is large (the STS3215 with a third of its motor friction, 20x s3: massless -24.4 %, the horn -13.6 %,
its interval [0.66, 0.98] of the truth without the mirror; the truth validates 7 % worse than the
massless fit there, so no profile over the horn's play reaches it). Without the rebound named it is not run: on twins whose contact does not
rebound it moves the play by up to 28 points.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from servoid.ident.diagnosis.flank_rebound import rebound
from servoid.ident.diagnosis.friction_stall import stall_band
from servoid.ident.metrics import free_run_nrmse, nrmse
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import loop_fit as lf

__all__ = ["HORN_CONTACT", "MU", "REASON", "with_horn", "held_play_fit"]

#: Whether :func:`~servoid.ident.offline.second_structure.second_structure` runs the stage.
HORN_CONTACT = True
#: The horn's inertia ratio to the motor seen through the gear, held (the twins' horns on a bench load: 0.026-0.04).
MU = 0.03
#: The contact's start: natural frequency on the horn's inertia (rad/s) and damping ratio.
WC_START, ZETA_START = 500.0, 0.2
#: The horn friction's start, times the massless Coulomb level.
AL_START = 2.0
#: Each least squares' budget on the window (function evaluations).
NFEV = 60
#: The horn's parameters fitted besides the loop and the play.
HORN = ("al", "wc", "zeta")
#: The profile over the play (:func:`_profiled`): the play held at these multiples of the final refit's play, every
#: other parameter refitted on every sample, walked outwards from it on either side (each point from its neighbour's
#: fit) until the cost rises at :data:`PROFILE_RISES` points in a row; the lowest point, where it costs less, starts
#: the refit on every sample again (empty: no profile). The two stages from the massless fit stop short on this rough
#: cost: on the STS3215 twin's live records (seeds 0-3, the slow phase and 15 / 20 / 25 s / all of the fast part) the
#: profile over 0.8-1.1x the truth (two starts a point) of 11 of the 12 kept horns has a point that costs 0.9-30 %
#: less than the stage's answer (at 0.80-1.04x the truth); its lowest lay at 0.95-1.05x on 11, at the grid's 1.10x on one (
#: ``benchmarks/horn_profile.py``). The grid reaches further up than down: the stage starts from the massless play,
#: which the rebound biases low. On the search's window's estimation blocks instead (before the keep rule) it sent
#: three of those answers to -17 ... -28 %: the window's minimum is not the record's.
PLAY_PROFILE: tuple[float, ...] = (0.92, 0.85, 1.08, 1.17, 1.26, 1.36)
#: ... walked in one direction until this many points in a row cost more than the lowest so far.
PROFILE_RISES = 2
#: The doubt a kept stage adds.
REASON = (
    "flank_rebound: the play comes from a light horn on a compliant gear contact fitted to the load's rebound "
    "(STS3215 twin: -9 ... -2 %), whose interval is not yet calibrated"
)


def _values(model: Any) -> dict[str, float]:
    """A fitted model's values in the fit's own names (``play``, ``asym``)."""
    d = {k: float(v) for k, v in model.params().items()}
    d["play"] = float(model.play)
    d["asym"] = (model.c1 - model.c2) / (2.0 * model.play) if model.play > 0.0 else 0.0
    return d


def with_horn(
    u: np.ndarray, y: np.ndarray, period: float, choice: lf.LoopChoice, keep: np.ndarray | None = None
) -> lf.LoopChoice:
    """``choice`` (:func:`~servoid.ident.offline.loop_fit.fit_loop`'s) with the horn stage where it applies.

    Parameters
    ----------
    u, y : ndarray
        The record fit_loop was given.
    period : float
        The host period, s.
    choice : LoopChoice
        fit_loop's answer.
    keep : ndarray of bool, optional
        fit_loop's scored readings (a live record's validity mask: lost and late readings False,
        their ``y`` may be NaN). As in fit_loop, the model runs through every sample, ``y`` is read
        bridged across the gaps for the starts, and the rebound, the fit, the validation, the NRMSE
        and the interval read kept readings only. Default: all kept.

    Returns
    -------
    LoopChoice
        ``choice`` itself where the play is not in the loop, the rebound is not named or the horn
        does not validate better; otherwise the horn's answer (play, model, fit, interval, a doubt).
    """
    if not HORN_CONTACT or choice.structure != PLAY_IN_LOOP:
        return choice
    u_arr, y_arr, kept, _ = lf._checked(u, y, period, keep)
    if not rebound(y_arr, np.asarray(choice.simulated), float(choice.play), period, valid=kept).named:
        return choice
    t0 = time.perf_counter()
    cand = min((c for c in choice.candidates if c.structure == PLAY_IN_LOOP), key=lambda c: c.validation_nrmse)
    n = u_arr.size
    w = lf.SEARCH_SAMPLES if n >= 2 * lf.SEARCH_SAMPLES else n
    centre = float(np.mean(u_arr))
    uc = np.ascontiguousarray(u_arr - centre)
    yc = np.ascontiguousarray(y_arr - centre)
    us, ys = uc[:w], yc[:w]
    _, kv = lf._linear_start(us, ys, period)
    v_typ = float(np.std(np.diff(ys))) / period
    a_scale = 0.1 * kv * v_typ
    # fit_loop's blocks: estimation and validation on the window's kept readings
    est, val = lf.block_mask(w) & kept[:w], ~lf.block_mask(w) & kept[:w]
    val0 = free_run_nrmse(ys[val], cand.model.simulate(us, y0=float(ys[0]))[val])
    d0 = _values(cand.model)
    start = dict(d0, mu=MU, e=0.0, al=AL_START * d0["fc"], wc=WC_START, zeta=ZETA_START)
    if start["fs"] <= start["fc"]:  # the searches lose the hump (loop_fit._final_fit): restart from one
        start.update(fs=lf.HUMP_RESTART * start["fc"], vs=max(start["vs"], lf.HUMP_VS * v_typ))
    loop = lf._free(PLAY_IN_LOOP, cand.integrator)
    evaluations = 0
    d = start
    for free in (("play", *HORN), loop + HORN):
        d, prob, _ = lf._fit(us, ys, period, PLAY_IN_LOOP, d, est, a_scale, integrator=cand.integrator,
                             max_nfev=NFEV, free=free)  # fmt: skip
        evaluations += prob.evaluations
    horn_val = free_run_nrmse(ys[val], lf._model(PLAY_IN_LOOP, period, d).simulate(us, y0=float(ys[0]))[val])
    if not horn_val < (1.0 - lf.LOAD_MARGIN) * val0:
        return replace(choice, evaluations=choice.evaluations + evaluations)
    d, prob, sol = lf._fit(uc, yc, period, PLAY_IN_LOOP, d, kept, a_scale, integrator=cand.integrator,
                           max_nfev=lf.FINAL_NFEV, free=loop + HORN)  # fmt: skip
    evaluations += prob.evaluations
    profiled, used = _profiled(uc, yc, period, d, kept, a_scale, cand.integrator, loop + HORN)
    evaluations += used
    if profiled is not d:  # a lower cost elsewhere on the profile: the final fit from there
        d, prob, sol = lf._fit(uc, yc, period, PLAY_IN_LOOP, profiled, kept, a_scale, integrator=cand.integrator,
                               max_nfev=lf.FINAL_NFEV, free=loop + HORN)  # fmt: skip
        evaluations += prob.evaluations
    final = lf._model(PLAY_IN_LOOP, period, d)
    simulated = final.simulate(uc, y0=float(yc[0]))
    lo, hi = (math.nan, math.nan)
    if sol is not None:
        lo, hi = lf._play_interval(*lf._spaced(sol.jac, sol.fun, kept), prob.free, d["play"])
    interval = (lo, hi)
    if math.isfinite(lo + hi):
        # the massless play is a rival the record does not exclude, and the horn's correction of it is as
        # uncertain as it is large: the truth may lie as far past the horn's play (the mirror) as the massless short of it
        mirror = max(2.0 * final.play - float(choice.play), 0.0)
        interval = (min(lo, float(choice.play), mirror), max(hi, float(choice.play), mirror))
    return replace(
        choice,
        play=final.play,
        play_interval=interval,
        fit_nrmse=nrmse(yc[kept], simulated[kept]),
        params=final.params(),
        simulated=simulated + centre,
        reasons=(*choice.reasons, REASON),
        stall_band=stall_band(max(final.fs, final.fc), final.kv, final.kp),
        model=final,
        seconds=choice.seconds + time.perf_counter() - t0,
        evaluations=choice.evaluations + evaluations,
    )


def _profiled(
    u: np.ndarray,
    y: np.ndarray,
    period: float,
    d: dict[str, float],
    score: np.ndarray,
    a_scale: float,
    integrator: bool,
    free: tuple[str, ...],
) -> tuple[dict[str, float], int]:
    """``d``, or the lowest point of :data:`PLAY_PROFILE`'s profile over the play where it costs less on ``score``;
    and the simulations spent."""
    if not PLAY_PROFILE:
        return d, 0
    base = lf._cost(u, y, period, PLAY_IN_LOOP, d, score)
    spent = 1
    best = (base, d)
    for side in (sorted(f for f in PLAY_PROFILE if f < 1.0)[::-1], sorted(f for f in PLAY_PROFILE if f > 1.0)):
        start, rises = d, 0
        for factor in side:
            fitted, cost, used = held_play_fit(u, y, period, start, factor * d["play"], score, a_scale, integrator,
                                               free, max_nfev=NFEV)  # fmt: skip
            spent += used
            start = fitted
            if cost < best[0]:
                best, rises = (cost, fitted), 0
            else:
                rises += 1
                if rises >= PROFILE_RISES:
                    break
    return best[1], spent


def held_play_fit(
    u: np.ndarray,
    y: np.ndarray,
    period: float,
    d: dict[str, float],
    play: float,
    score: np.ndarray,
    a_scale: float,
    integrator: bool,
    free: tuple[str, ...],
    *,
    max_nfev: int,
) -> tuple[dict[str, float], float, int]:
    """``d`` refitted with its play held at ``play`` (every other name of ``free`` refitted): one point of a profile
    over the play (:func:`_profiled`, ``benchmarks/horn_profile.py``). Returns the fit, its cost on ``score`` and the
    simulations spent."""
    held = tuple(n for n in free if n != "play")
    fitted, prob, _ = lf._fit(u, y, period, PLAY_IN_LOOP, dict(d, play=play), score, a_scale, integrator=integrator,
                              max_nfev=max_nfev, free=held, ftol=lf.FTOL, stall=lf.STALL)  # fmt: skip
    return fitted, lf._cost(u, y, period, PLAY_IN_LOOP, fitted, score), prob.evaluations + 1
