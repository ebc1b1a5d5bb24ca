"""The play alone fitted on a short window, every other parameter of a servo-loop model held: a search over a grid of plays.

Wear changes the play, not the loop, so the monitor's estimate on a short
window has one unknown: the scale ``s`` of the play (``c1`` and ``c2`` both
scaled, their ratio held). Its free-run cost is rough on fine scales (the
simulation's sub-steps; a 3 % finite-difference slope of a trust region stops
where the last answer was, and successive estimates then repeat one value),
so the play is found by evaluating the cost on a fixed coarse grid of scales
(:data:`COARSE`, log-spaced by :data:`COARSE_STEP`, 0.2x .. 10x the held model's
play: a model file's play may be far off), then on a fine grid (:data:`STEP`)
around the best coarse point, and refining the best fine point by a parabola
through it and its neighbours. Each estimate starts from the held model, not
from the previous estimate: estimates of windows that do not overlap are then
independent. A search costs about 50 simulations of the window (320 samples
at 200 Hz: a few milliseconds, compiled).

A massless load's simulation runs on sub-steps of at most :data:`SUBSTEP_S`
(:func:`fit_substeps`), finer than the held model's own where those are coarser:
with the play in the loop, the load stops and starts as the motor meets a flank,
and the cost of a window with two or three reversals moves in jumps as those
events cross the sub-step grid. On the XM430 twin (the held loop's 6 sub-steps
at 200 Hz, 0.83 ms) the window plays of one seed hopped between valleys at
0.76 / 0.80 / 0.89 / 0.91x the play, repeating with the steady sine's segment
(``benchmarks/monitor_loop.py``, seed 6: scatter 9.8 %, the alarm 2.00 s after
a +20 % step); on 25 sub-steps (0.2 ms) they scattered 1.2 % and the alarm came
after 1.25 s (docs/monitor.md). A massive load (a horn, a load model) keeps the
held model's sub-steps: its simulation costs 24-40x a massless one, and the
benchmark's massive files' window plays scattered 0.1-1.8 % without it.
"""

from __future__ import annotations

import math

import numpy as np

from servoid.ident.models.servo_loop import PARAM_NAMES, ServoLoopModel, simulate_kernel

__all__ = ["fit_play", "fit_substeps", "COARSE", "COARSE_STEP", "STEP", "SUBSTEP_S"]

#: Log-spacing of the coarse grid of play scales, and of the fine one.
COARSE_STEP = 0.1
STEP = 0.025
#: The coarse grid, relative to the held model's play: 0.2x .. 10x.
COARSE = np.exp(np.arange(math.log(0.2), math.log(10.0) + COARSE_STEP / 2, COARSE_STEP))
_FINE = np.arange(-round(COARSE_STEP / STEP), round(COARSE_STEP / STEP) + 1) * STEP

#: Longest sub-step of the play fit's simulation of a massless load, s (the module's text).
SUBSTEP_S = 2e-4

_C1, _C2 = PARAM_NAMES.index("c1"), PARAM_NAMES.index("c2")


def fit_substeps(held: ServoLoopModel) -> int:
    """Sub-steps per period of the play fit's simulation: the held model's, at least a :data:`SUBSTEP_S` grid where its load is massless.

    Parameters
    ----------
    held : ServoLoopModel
        The held model.
    """
    if held.massive:
        return held.substeps
    return max(held.substeps, math.ceil(held.sample_period_s / SUBSTEP_S - 1e-9))


def fit_play(u: np.ndarray, y: np.ndarray, score: np.ndarray, held: ServoLoopModel) -> tuple[ServoLoopModel, float]:
    """The model with the play that fits the window best, every other parameter ``held``'s.

    Parameters
    ----------
    u, y : ndarray
        Set points and readings of the window at ``held``'s period; ``y[0]`` measured (the
        simulation starts there, at rest), others anything where ``score`` is False.
    score : ndarray of bool
        Samples scored (not the burn-in, not lost samples); at least 2.
    held : ServoLoopModel
        The model whose parameters are held (its play is the grid's centre; it must be > 0).

    Returns
    -------
    tuple
        The model with the fitted play, and its free-run NRMSE on the scored samples.
    """
    centre = float(np.mean(u))
    uc = np.ascontiguousarray(u - centre, dtype=np.float64)
    target = y[score] - centre
    stop = int(np.flatnonzero(score)[-1]) + 1
    sel = score[:stop]
    out = np.empty(stop)
    p = held.vector()
    c1, c2 = p[_C1], p[_C2]
    fb, period, m, y0 = held.feedback_load, held.sample_period_s, fit_substeps(held), float(y[0]) - centre

    def costs(scales: np.ndarray) -> np.ndarray:
        cost = np.empty(scales.size)
        for i, g in enumerate(scales):
            p[_C1], p[_C2] = c1 * g, c2 * g
            simulate_kernel(p, fb, uc, y0, period, m, out)
            r = out[sel] - target
            cost[i] = float(np.dot(r, r)) if np.all(np.isfinite(r)) else math.inf
        return cost

    coarse = math.log(COARSE[int(np.argmin(costs(COARSE)))])
    fine = coarse + _FINE
    cost = costs(np.exp(fine))
    best = int(np.argmin(cost))
    x = float(fine[best])
    if 0 < best < fine.size - 1:
        lo, mid, hi = cost[best - 1], cost[best], cost[best + 1]
        curve = lo - 2.0 * mid + hi
        if curve > 0.0:  # the parabola's vertex, within one step of the best point
            x += STEP * float(np.clip(0.5 * (lo - hi) / curve, -1.0, 1.0))
    g = math.exp(x)
    p[_C1], p[_C2] = c1 * g, c2 * g
    model = ServoLoopModel.from_vector(held.structure, period, p)
    # the NRMSE of the best grid point (within half a step of the returned play)
    spread = float(np.std(target))
    return model, math.sqrt(float(cost[best]) / target.size) / spread if spread > 0.0 else math.nan
