"""The load stage of the servo-loop fit: a load of its own inertia meeting the flanks in impacts, found on a grid.

The model's load (:func:`~servoid.ident.models.servo_loop._advance_load`): the inertia ratio
``mu`` (load over motor side, at the output), the restitution ``e`` of an impact on a flank and
the load's own friction ``al`` (a deceleration). A heavy load behind the play coasts across it
after each reversal; the massless play operator cannot follow that and books it as a small play
(the ODrive twin, ``mu`` 2.8: -80 %).

Why a grid with the loop refitted at each point (issue 12, massload session): least squares
started from the massless optimum stays at a near-massless local minimum, even on the model's
own noise-free simulation, because the loop's rates, friction and play absorb what a small
``mu`` explains and the cost rises before it falls. So each point of :data:`MU_GRID` x
:data:`E_GRID` holds ``mu`` and ``e`` and refits the loop's rates, its friction, the play and
``al`` (:data:`GRID_FREE`) on the estimation blocks; least squares over everything then starts
from the best point (:data:`FINAL_FREE`). A winner with an integrator runs the grid a second time
with ``ki`` refitted too (:data:`GRID_FREE_KI`) where the first pass's answer is kept, and the
pass that ends lower on the estimation blocks answers. :func:`fit_loop <servoid.ident.offline.loop_fit.fit_loop>`
keeps the result only when it validates a parsimony margin better than the massless winner.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from servoid.ident.metrics import free_run_nrmse
from servoid.ident.models.servo_loop import LOAD_NAMES

__all__ = [
    "MU_GRID",
    "MU_LIMITS",
    "E_GRID",
    "PLAY_FACTORS",
    "GRID_FREE",
    "GRID_FREE_KI",
    "GRID_NFEV",
    "FINAL_NFEV",
    "PROFILE_NFEV",
    "Fit",
    "Simulate",
    "load_stage",
    "floor_rivals",
    "FLOOR_MU_GRID",
    "FLOOR_E_GRID",
]

#: A least-squares fit on the estimation blocks from a start with some names free and a budget:
#: its values, its cost (inf when it failed) and the simulations it took.
Fit = Callable[[dict[str, float], tuple[str, ...], int], tuple[dict[str, float], float, int]]
#: The free-run simulation of a set of values over the whole record.
Simulate = Callable[[dict[str, float]], np.ndarray]

#: Inertia ratios held on the grid: a light horn to a load three times the motor side (the twins:
#: horn servos 0.03-0.04, the CiA 402 0.9, the ODrive 2.8); ``mu = 0`` is the massless winner itself.
MU_GRID = (0.3, 1.0, 3.0)
#: The inertia ratio's range in every fit of a massive load (the grid's a third below and three times above):
#: the stage looks for a heavy load; a light one is the horn servos' question, and towards ``mu = 0`` a
#: weightless load that coasts fits the ODrive twin's record at 50x 3 % better than the heavy one, with
#: the play 11 % small.
MU_LIMITS = (0.1, 10.0)
#: The loads :func:`floor_rivals` fits where the massless winner is at its floor: a light and a
#: middling load, plastic and lightly damped impacts (a bouncing light load hides play there).
FLOOR_MU_GRID = (0.3, 1.0)
FLOOR_E_GRID = (0.0, 0.8)
#: Restitutions held on the grid: plastic to lightly damped (a gear contact of 5 % damping: 0.85).
E_GRID = (0.0, 0.5, 0.8)
#: The plays each grid point simulates first, as multiples of the massless winner's (the ODrive twin's
#: massless play is a fifth of the truth: the load coasts across the rest).
PLAY_FACTORS = (0.5, 1.0, 2.0, 4.0, 8.0)
#: The massless fit's values that are per the motor side's inertia: a grid point starts them ``1 + mu``
#: times larger, so that the pair in contact starts as the massless loop (the ODrive twin's ``kv``
#: with the true ``mu`` is four times the massless fit's).
_PER_INERTIA = ("kv", "ki", "fc", "fs", "a0")
#: What each grid point refits around its ``mu`` and ``e``: the loop's rates, the friction, the play and
#: the load's friction; and its budget (scipy's ``max_nfev``).
GRID_FREE = ("kp", "kv", "fc", "play", "al")
GRID_NFEV = 12
#: The grid's second pass where the winner has an integrator: ``ki`` refitted too. On the ODrive twin's
#: sines (10x s1, 20x s1, 20x s2) it moved the play -10.2 -> -1.3 %, +1.8 -> -0.4 %, +4.3 -> -9.0 %,
#: and in each the pass that ended lower on the estimation blocks was the closer one.
GRID_FREE_KI = GRID_FREE + ("ki",)
#: The final least squares from the best grid point: these and the massless candidate's own free parameters.
FINAL_FREE = LOAD_NAMES
FINAL_NFEV = 30
#: The profile over the inertia after it (each value of :data:`MU_GRID` held, everything else refitted): its budget.
PROFILE_NFEV = 20


def load_stage(
    y: np.ndarray,
    best_d: dict[str, float],
    free: tuple[str, ...],
    fit: Fit,
    simulate: Simulate,
    est: np.ndarray,
    val: np.ndarray,
    kept_below: float = np.inf,
) -> tuple[dict[str, float], int, list[tuple[float, float]]]:
    """The massless winner extended by a massive load: the grid with the loop refitted, then least squares.

    Parameters
    ----------
    y : ndarray
        The centred record's readings.
    best_d : dict
        The massless winner's fitted values (the fit's own names: ``play``, ``asym`` ...), the start
        of every grid point.
    free : tuple of str
        The massless winner's free parameters (its place of the play and integrator decide them).
    fit : callable
        :data:`Fit`: least squares of the winner's structure on the estimation blocks.
    simulate : callable
        :data:`Simulate`: the winner's structure simulated from a set of values.
    est, val : ndarray of bool
        The estimation and the validation samples.
    kept_below : float, optional
        The validation NRMSE under which the caller keeps the stage's answer: the second pass
        (``ki`` refitted) runs only where the first one's answer is kept (default: always).

    Returns
    -------
    values : dict
        The stage's fitted values (estimation blocks); kept or not is the caller's choice.
    evaluations : int
        Simulations it took.
    rivals : list of (float, float)
        The play and the validation NRMSE of every grid point and of the profile's fits (of both
        passes when there are two): the models the record may not separate (:func:`~servoid.ident.offline.loop_fit.widened_to_rivals`).
    """
    # both passes below start from the same grid
    starts, evaluations = _grid_starts(y, best_d, simulate, est, MU_GRID, E_GRID)
    score, d, used, rivals = _from_grid(y, starts, free, GRID_FREE, fit, simulate, est, val)
    evaluations += used
    if "ki" not in free:
        return d, evaluations, rivals
    # with an integrator the grid runs again with ki refitted too, and the pass that ends lower on the
    # estimation blocks answers: neither wins everywhere on the ODrive twin (see GRID_FREE_KI). Only
    # where the first answer is kept: elsewhere (the horn twins' motor-side candidates, 9 records) the
    # second was not kept either and only doubled the stage's cost
    evaluations += 1
    if not free_run_nrmse(y[val], simulate(d)[val]) < kept_below:
        return d, evaluations, rivals
    score_ki, d_ki, used, tried = _from_grid(y, starts, free, GRID_FREE_KI, fit, simulate, est, val)
    evaluations += used
    # both passes' models are rivals: the record may not separate them either
    return (d_ki if score_ki < score else d), evaluations, rivals + tried


def floor_rivals(
    y: np.ndarray, best_d: dict[str, float], fit: Fit, simulate: Simulate, est: np.ndarray, val: np.ndarray
) -> tuple[list[tuple[float, float]], int]:
    """Light and heavy loads that fit a record the massless winner holds at its floor: the play's rivals only.

    Where the massless winner fits at the record's floor the stage does not run (nothing is left for a
    load to explain), yet a load that bounces off the flanks can hide there behind a smaller play: the
    ODrive twin with a tenth of its load (``mu`` 0.28) is held at 0.98 times the floor by a massless
    play 25-32 % small, whose interval missed the truth. Each point of :data:`FLOOR_MU_GRID` x
    :data:`FLOOR_E_GRID` is fitted as a grid point of :func:`load_stage` (:data:`GRID_FREE`,
    :data:`GRID_NFEV`); its play and validation NRMSE are a rival for the interval
    (:func:`~servoid.ident.offline.loop_fit.widened_to_rivals`), never the answer.

    Parameters
    ----------
    y, best_d, fit, simulate, est, val
        As for :func:`load_stage`.

    Returns
    -------
    rivals : list of (float, float)
        Each point's play and validation NRMSE.
    evaluations : int
        Simulations it took.
    """
    starts, evaluations = _grid_starts(y, best_d, simulate, est, FLOOR_MU_GRID, FLOOR_E_GRID)
    rivals = []
    for start in starts:
        d, _, used = fit(start, GRID_FREE, GRID_NFEV)
        evaluations += used + 1
        rivals.append((d["play"], free_run_nrmse(y[val], simulate(d)[val])))
    return rivals, evaluations


def _grid_starts(
    y: np.ndarray,
    best_d: dict[str, float],
    simulate: Simulate,
    est: np.ndarray,
    mus: tuple[float, ...],
    es: tuple[float, ...],
) -> tuple[list[dict[str, float]], int]:
    """The start of each grid point (``mus`` x ``es``): the play of :data:`PLAY_FACTORS` that simulates best.

    The play is simulated at every grid point, not fitted: a coasting load hides part of it from the
    massless fit. Returns the starts and the simulations they took.
    """
    starts: list[dict[str, float]] = []
    evaluations = 0
    for mu in mus:
        for e in es:
            tries = []
            for factor in PLAY_FACTORS:
                start = dict(best_d)
                # the same loop when the load rests on a flank: (1 + mu) dv/dt = kv (v_cmd - v) + z + a0 - F(v)
                for name in _PER_INERTIA:
                    start[name] = (1.0 + mu) * best_d[name]
                start.update(mu=mu, e=e, al=best_d["al"], play=factor * best_d["play"])
                # a grid point can run away (a load the loop cannot hold): it fits infinitely badly, not an error
                tries.append((free_run_nrmse(y[est], simulate(start)[est]), start))
            evaluations += len(tries)
            starts.append(min(tries, key=lambda c: c[0])[1])
    return starts, evaluations


def _from_grid(
    y: np.ndarray,
    starts: list[dict[str, float]],
    free: tuple[str, ...],
    grid_free: tuple[str, ...],
    fit: Fit,
    simulate: Simulate,
    est: np.ndarray,
    val: np.ndarray,
) -> tuple[float, dict[str, float], int, list[tuple[float, float]]]:
    """One pass of the stage: each grid point refitted with ``grid_free``, least squares from the best, the profile.

    Returns the answer's estimation NRMSE, the answer, the simulations it took and its rivals (as
    :func:`load_stage`).
    """
    evaluations = 0
    points: list[tuple[float, dict[str, float]]] = []
    rivals: list[tuple[float, float]] = []
    for start in starts:
        d, cost, used = fit(start, grid_free, GRID_NFEV)
        evaluations += used
        points.append((cost, d))
        # every point is a rival: its play joins the interval when it validates as well as the answer
        rivals.append((d["play"], free_run_nrmse(y[val], simulate(d)[val])))
    d = min(points, key=lambda c: c[0])[1]
    free = free + FINAL_FREE
    d, _, used = fit(d, free, FINAL_NFEV)
    evaluations += used
    # the profile over the inertia: the answer refitted with each grid value held; the best on the
    # estimation blocks answers, and every one is a rival (the play moves with mu where the record is flat)
    fits: list[dict[str, float]] = [d]
    held = tuple(n for n in free if n != "mu")
    for mu in MU_GRID:
        start = dict(d)
        for name in _PER_INERTIA:
            start[name] = d[name] * (1.0 + mu) / (1.0 + d["mu"])
        start["mu"] = mu
        held_fit, _, used = fit(start, held, PROFILE_NFEV)
        evaluations += used
        fits.append(held_fit)
    scored = []
    for values in fits:
        y_hat = simulate(values)
        scored.append((free_run_nrmse(y[est], y_hat[est]), values))
        rivals.append((values["play"], free_run_nrmse(y[val], y_hat[val])))
    score, d = min(scored, key=lambda c: c[0])
    return score, d, evaluations, rivals
