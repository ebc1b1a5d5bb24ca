"""The offline refinement of the servo-loop model's online estimate: one answer, warm-started from it.

A live session's moving-window refit (:mod:`servoid.ident.online.window`) ends
with a model of the last window. The whole record is then refined **from
it** -- not fitted a second time from scratch, which gave a second,
different answer in the same output (issue 15: -17 % online, -12 % from
scratch, on the XM430 twin) -- and the refinement is reported as the online
estimate's, with the online-vs-refined gap as its convergence check
(:func:`~servoid.ident.online.verdict.judge_window`).

:func:`refine_online` keeps what makes :func:`~servoid.ident.offline.loop_fit.fit_loop`'s
answer honest, warm:

1. the online model is refitted on the whole record (every usable sample;
   :func:`~servoid.ident.offline.loop_fit.refit_loop`), and so is it with its
   play :data:`REACH` smaller and larger: a refit only moves the play as far as
   the record pulls it (on the XM430 twin's demo record refits from 0.8x and
   1.2x the play stayed at 0.8x and 1.2x, their fits 0.1 % apart: the record
   does not pin the play there, and a refinement from one start alone would
   agree with any online estimate). The refinement the online estimate is
   judged against (:func:`~servoid.ident.online.verdict.judge_window`) is the
   one from the online model, unless another fits better by more than
   :data:`TIE` (then the record pulls the play away from the online estimate);
2. the place of the play is still chosen by validation: both places are
   refitted on the estimation blocks (:func:`~servoid.ident.offline.loop_fit.block_mask`),
   the refinement's from it, the other from the first window's best
   model of that place (:attr:`WindowResult.rival`; else the online model with
   the play moved), and scored on the validation blocks; the margin between
   them is the structure rule's number;
3. when the other place validates better, it is refined as step 1 refines
   the online model (on the whole record, from its play and 0.8x and 1.2x
   of it) and answers; the play's 95 % interval is the answer's HAC interval
   widened to the plays of the models the record cannot tell from it: the
   other place when it validates within
   :data:`~servoid.ident.offline.intervals.MIN_STRUCTURE_MARGIN` (the rule of
   ``fit_loop``'s interval), and the answer's place's refits whose fit is
   within that margin of the answer's.

Cost: five warm refits (about 3 s on 40 s at 140 Hz; eight when the place switches) instead of ``fit_loop``'s
scans, four candidates and final fit.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.diagnosis.friction_stall import stall_band
from servoid.ident.metrics import nrmse
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
from servoid.ident.offline.intervals import quantum
from servoid.ident.offline.loop_fit import (
    FINAL_NFEV,
    MIN_SAMPLES,
    LoopCandidate,
    LoopChoice,
    LoopRefit,
    _dead_time_samples,
    _noticed,
    _with_rivals,
    block_mask,
    refit_loop,
    widened_to_rivals,
)
from servoid.ident.online.window import WindowResult

__all__ = ["refine_online", "WARM_NFEV", "REACH", "TIE"]

#: scipy's ``max_nfev`` of each place's warm refit on the estimation blocks (the start is near:
#: fewer than ``fit_loop``'s 15 + 40 from a scan).
WARM_NFEV = 15
#: Relative change of the play the refinement also starts from, both ways (step 1).
REACH = 0.2
#: A refit from a moved play replaces the one from the online model only when its fit NRMSE is
#: lower by more than this share: fits closer than that are the valley's floor, not a direction.
TIE = 0.01


def refine_online(u: Any, y: Any, online: WindowResult, *, keep: Any = None) -> tuple[LoopChoice, LoopRefit]:
    """Refine the online estimate on the whole record and choose the place of the play by validation (the module's steps).

    Parameters
    ----------
    u, y : array_like
        The record at the online estimate's sample period (``y`` is not read where ``keep`` is False);
        ``y[0]`` must be measured.
    online : WindowResult
        The window refit's run; its :attr:`~WindowResult.model` is the start.
    keep : array_like of bool, optional
        The usable samples (a live session's validity mask); default all.

    Returns
    -------
    choice : LoopChoice
        The answer, as :func:`~servoid.ident.offline.loop_fit.fit_loop` gives one (what
        :func:`servoid.ident.identify.identify` takes as ``loop=``).
    refit : LoopRefit
        The refinement of step 1 (the online model's place of the play): what the online
        estimate is judged against.

    Raises
    ------
    ConfigError
        No online model, mismatched signals or fewer than
        :data:`~servoid.ident.offline.loop_fit.MIN_SAMPLES` usable samples.
    """
    t0 = time.perf_counter()
    start = online.model
    if start is None:
        raise ConfigError("the online estimate has no model (no window was fitted): nothing to refine")
    u_arr = validation.signal("u", u, min_length=MIN_SAMPLES)
    y_arr = np.asarray(y, dtype=np.float64)
    kept = np.ones(u_arr.size, dtype=bool) if keep is None else np.asarray(keep, dtype=np.bool_)
    if y_arr.shape != u_arr.shape or kept.shape != u_arr.shape:
        raise ConfigError(f"u, y and keep differ in shape: {u_arr.shape}, {y_arr.shape}, {kept.shape}")
    if int(kept.sum()) < MIN_SAMPLES:
        raise ConfigError(f"{int(kept.sum())} usable samples; the servo-loop refinement needs at least {MIN_SAMPLES}")
    # 1. the online model on the whole record, and from a smaller and a larger play: the best fit is the refinement
    whole, refits = _refine(u_arr, y_arr, start, kept)
    spent = list(refits)
    # 2. both places on the estimation blocks, scored on the validation blocks
    blocks = block_mask(u_arr.size)
    est, val = blocks & kept, ~blocks & kept
    other = PLAY_IN_LOOP if start.structure == OUTPUT_BACKLASH else OUTPUT_BACKLASH
    rival = online.rival if online.rival is not None else dataclasses.replace(start, structure=other)
    centre = float(np.mean(u_arr))
    uc, yc = u_arr - centre, np.where(kept, y_arr, y_arr[0]) - centre
    candidates = []
    for begin in (whole.model, rival):
        fit = refit_loop(u_arr, y_arr, begin, score=est, max_nfev=WARM_NFEV)
        y_hat = fit.model.simulate(uc, y0=float(yc[0]))
        candidates.append(
            LoopCandidate(
                fit.model.structure,
                fit.model.ki > 0.0,
                fit.model,
                nrmse(yc[est], y_hat[est]),
                nrmse(yc[val], y_hat[val]),
                fit.evaluations,
            )
        )
    candidates.sort(key=lambda c: c.validation_nrmse)
    best = candidates[0]
    per_structure = {c.structure: c.validation_nrmse for c in candidates}
    worse = candidates[1].validation_nrmse
    margin = worse / best.validation_nrmse - 1.0 if best.validation_nrmse > 0.0 else math.inf
    # 3. the answer: the refinement when validation keeps the online place of the play, else the other refitted
    if best.structure != start.structure:  # the other place, refined as step 1 refines the online model
        final, refits = _refine(u_arr, y_arr, best.model, kept)
        spent += refits
    else:
        final = whole
    model: ServoLoopModel = final.model
    simulated = model.simulate(uc, y0=float(yc[0]))
    inside = (
        model if model.structure == PLAY_IN_LOOP else next(c.model for c in candidates if c.structure == PLAY_IN_LOOP)
    )
    evaluations = sum(r.evaluations for r in spent) + sum(c.evaluations for c in candidates)
    choice = LoopChoice(
        structure=model.structure,
        play=model.play,
        play_interval=_reach(_with_rivals(final.play_interval, candidates, best.validation_nrmse), refits, final),
        fit_nrmse=final.fit_nrmse,
        validation_nrmse=per_structure,
        margin=float(margin),
        params=model.params(),
        simulated=simulated + centre,
        reasons=_noticed(model, quantum(yc[kept])),
        dead_time_samples=_dead_time_samples(inside, uc[kept], yc[kept]),
        stall_band=stall_band(model.fs, model.kv, model.kp),
        model=model,
        candidates=tuple(candidates),
        seconds=time.perf_counter() - t0,
        evaluations=evaluations,
    )
    return choice, whole


def _refine(u: np.ndarray, y: np.ndarray, model: ServoLoopModel, kept: np.ndarray) -> tuple[LoopRefit, list[LoopRefit]]:
    """Step 1 for one place of the play: ``model`` refitted on the whole record, and from its play moved by
    :data:`REACH` both ways; the refinement (the first unless another fits better by more than :data:`TIE`) and all three.
    """
    refits = [refit_loop(u, y, _scaled(model, f), score=kept, max_nfev=FINAL_NFEV) for f in (1.0, 1 - REACH, 1 + REACH)]
    best = min(refits, key=lambda r: r.fit_nrmse)
    return (best if best.fit_nrmse < (1.0 - TIE) * refits[0].fit_nrmse else refits[0]), refits


def _scaled(model: ServoLoopModel, factor: float) -> ServoLoopModel:
    """``model`` with its play (both sides) times ``factor``."""
    return dataclasses.replace(model, c1=model.c1 * factor, c2=model.c2 * factor)


def _reach(interval: tuple[float, float], refits: list[LoopRefit], final: LoopRefit) -> tuple[float, float]:
    """``interval`` widened to the plays of the refits of one place that fit within the structure margin of the answer
    (step 3; a refit of the other place than the answer's says nothing of its play; an unbounded interval stays so)."""
    same_place = [(r.model.play, r.fit_nrmse) for r in refits if r.model.structure == final.model.structure]
    return widened_to_rivals(interval, same_place, final.fit_nrmse)
