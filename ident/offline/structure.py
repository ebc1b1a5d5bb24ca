"""Orders and delay of the pseudo-Wiener model chosen from the data: BIC with an SSE floor, the runner-up reported.

Each candidate ``(na, nb, d)`` is an output-error fit from rest
(:func:`~servoid.ident.offline.refine.refine` with the initial state, on a
record centred on its operating point), scored by

    BIC = N ln(SSE / N) + p ln N,        p = na + nb + 1 + 3 + 1 (delta0)

on a window of the record: the first :data:`WINDOW` samples, lengthened
until it holds :data:`MIN_REVERSALS` reversals of the output (a slow record
has few in its first seconds). The SSE is floored at ``N (1e-9 std y)^2``:
a noise-free record fits to rounding, every model that nests the true one
would tie at minus infinity and the pick among them would be a coin toss;
with the floor they tie and the penalty picks the smallest. The search
screens the delay first (``(2, 1, d)``), then the orders at that delay
(12 fits instead of 27; research study, Q1: 10/10 right on the paper's
plant, the criterion computed in ~0.5 s). The candidates that the best one
nests and that lost to it are scored again from the best one cut down to
their orders (:func:`_retry_nested`): a fit from the ARX start may stop
short of its optimum, and a bigger model would then win with coefficients
that are zero. Orders the caller fixes are not searched.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid.errors import ConfigError, ModelError
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.offline.intervals import reversal_indices
from servoid.ident.offline.refine import Refinement, arx_start, refine

__all__ = ["Candidate", "OrderChoice", "select_orders", "NA_GRID", "NB_GRID", "DELAY_GRID", "WINDOW"]

NA_GRID: tuple[int, ...] = (1, 2, 3)
NB_GRID: tuple[int, ...] = (0, 1, 2)
DELAY_GRID: tuple[int, ...] = (1, 2, 3)

#: Samples the criterion is computed on, at least (then the pick is refitted on all).
WINDOW = 3000
#: Output reversals the window must hold (it grows until it does, or holds the whole record).
MIN_REVERSALS = 10
#: Simulations per candidate while scoring.
SCORE_NFEV = 30
#: A BIC difference below this does not distinguish two candidates.
INDISTINCT_BIC = 2.0


@dataclass(frozen=True)
class Candidate:
    """One scored candidate.

    Attributes
    ----------
    na, nb, delay : int
        Its orders and delay.
    bic : float
        Its criterion on the window.
    nrmse : float
        Its free-run NRMSE on the window.
    play : float
        Its ``c1 + c2``.
    """

    na: int
    nb: int
    delay: int
    bic: float
    nrmse: float
    play: float

    @property
    def orders(self) -> tuple[int, int, int]:
        """``(na, nb, delay)``."""
        return self.na, self.nb, self.delay

    def to_dict(self) -> dict[str, Any]:
        """For JSON."""
        return {"na": self.na, "nb": self.nb, "delay": self.delay, "bic": self.bic, "nrmse": self.nrmse,
                "play": self.play}  # fmt: skip


@dataclass(frozen=True)
class OrderChoice:
    """The chosen orders, the runner-up and how the choice was made.

    Attributes
    ----------
    chosen : Candidate
        The smallest BIC.
    runner_up : Candidate or None
        The next smallest (None when only one candidate could be fitted).
    window : int
        Samples the criterion was computed on.
    candidates : tuple of Candidate
        Every candidate scored, best first.
    fixed : tuple of str
        The orders the caller fixed (not searched).
    start : BacklashModel
        The chosen candidate's model fitted on the window (a start for the final fit).
    delta0 : float
        Its initial state.
    """

    chosen: Candidate
    runner_up: Candidate | None
    window: int
    candidates: tuple[Candidate, ...]
    fixed: tuple[str, ...]
    start: BacklashModel
    delta0: float

    @property
    def bic_difference(self) -> float | None:
        """The runner-up's BIC minus the chosen one's (None without a runner-up)."""
        return None if self.runner_up is None else self.runner_up.bic - self.chosen.bic

    @property
    def distinct(self) -> bool:
        """Whether the runner-up is worse by at least :data:`INDISTINCT_BIC`."""
        d = self.bic_difference
        return d is None or d >= INDISTINCT_BIC

    def describe(self) -> str:
        """One line: the orders, the runner-up, the BIC difference and the runner-up's play."""
        c = self.chosen
        text = f"orders na={c.na}, nb={c.nb}, delay={c.delay} chosen by BIC on {self.window} samples"
        r = self.runner_up
        if r is not None:
            text += (f"; runner-up na={r.na}, nb={r.nb}, delay={r.delay}: BIC +{self.bic_difference:.3g}"
                     f"{'' if self.distinct else ' (not distinguishable)'}, its play {r.play:.4g}")  # fmt: skip
        return text

    def to_dict(self) -> dict[str, Any]:
        """For JSON: the chosen and runner-up candidates, the BIC difference, the window, the fixed orders."""
        return {
            "criterion": "bic", "chosen": self.chosen.to_dict(),
            "runner_up": None if self.runner_up is None else self.runner_up.to_dict(),
            "bic_difference": self.bic_difference, "distinct": self.distinct, "window": self.window,
            "fixed": list(self.fixed), "candidates": len(self.candidates),
        }  # fmt: skip


def criterion_window(y: np.ndarray, *, minimum: int = WINDOW, reversals: int = MIN_REVERSALS) -> int:
    """Length of the record's first part the criterion is computed on (see the module docstring)."""
    n = y.size
    if n <= minimum:
        return n
    turns = reversal_indices(y, 0.1 * float(np.std(y)))
    if turns.size < reversals:
        return n
    return int(max(minimum, min(n, turns[reversals - 1] + 1)))


def _score(
    u: np.ndarray, y: np.ndarray, na: int, nb: int, delay: int, floor: float, *, start: BacklashModel | None = None
) -> tuple[Candidate, Refinement]:
    if start is None:
        start = arx_start(u, y, na=na, nb=nb, delay=delay)
    fit = refine(u, y, start, max_nfev=SCORE_NFEV, initial_state=True)
    n = fit.residual.size
    sse = max(fit.sse, n * floor**2)
    p = fit.model.n_params + 1
    bic = n * float(np.log(sse / n)) + p * float(np.log(n))
    return Candidate(na, nb, delay, bic, fit.nrmse, fit.model.dead_zone), fit


def _nested_start(model: BacklashModel, na: int, nb: int) -> BacklashModel:
    """``model`` cut down to orders ``(na, nb)``: its first coefficients, its backlash."""
    return dataclasses.replace(model, a=tuple(model.a[:na]), b=tuple(model.b[: nb + 1]))


def _retry_nested(
    u: np.ndarray, y: np.ndarray, scored: dict[tuple[int, int, int], tuple[Candidate, Refinement]], floor: float
) -> None:
    """Score again, from the best candidate cut down to their orders, the candidates it nests that lost to it.

    A fit from the ARX start can stop short of its optimum within
    :data:`SCORE_NFEV` simulations (the ARX start's backlash is a small guess
    far from the truth); a bigger candidate that got there then wins on BIC
    although its extra coefficients are zero (paper's plant, SNR 43, 5 000
    samples: the true orders lost in 7 of 50 seeds by a BIC of 1100-3300, an
    SSE 1.5-3 times their optimum). The best candidate cut down to a nested
    candidate's orders is a start close to that candidate's optimum, so
    criteria are compared at optima; a refit that does not improve is
    ignored. Repeated while the best candidate changes (at most once per
    candidate).
    """
    tried: set[tuple[int, int, int]] = set()
    while True:
        best, best_fit = min(scored.values(), key=lambda cf: cf[0].bic)
        nested = [
            key for key in scored
            if key not in tried and key != best.orders and key[2] == best.delay and key[0] <= best.na
            and key[1] <= best.nb
        ]  # fmt: skip
        if not nested:
            return
        for key in nested:
            tried.add(key)
            try:
                again = _score(u, y, *key, floor, start=_nested_start(best_fit.model, key[0], key[1]))
            except (ConfigError, ModelError):
                continue
            if again[0].bic < scored[key][0].bic:
                scored[key] = again


def select_orders(
    u: np.ndarray,
    y: np.ndarray,
    *,
    na: int | None = None,
    nb: int | None = None,
    delay: int | None = None,
) -> OrderChoice:
    """Choose ``(na, nb, delay)`` by BIC on a window of a centred record.

    Parameters
    ----------
    u, y : ndarray
        The record, centred on its operating point
        (:mod:`servoid.ident.offline.operating_point`), without lost samples.
    na, nb, delay : int, optional
        Fix an order or the delay instead of searching it.

    Returns
    -------
    OrderChoice

    Raises
    ------
    ModelError
        When no candidate could be fitted.
    """
    n = criterion_window(y)
    uw, yw = np.ascontiguousarray(u[:n]), np.ascontiguousarray(y[:n])
    floor = 1e-9 * max(float(np.std(yw)), 1e-300)
    fixed = tuple(name for name, v in (("na", na), ("nb", nb), ("delay", delay)) if v is not None)
    scored: dict[tuple[int, int, int], tuple[Candidate, Refinement]] = {}

    def run(cand: tuple[int, int, int]) -> None:
        if cand in scored:
            return
        try:
            scored[cand] = _score(uw, yw, *cand, floor)
        except (ConfigError, ModelError):
            pass  # a candidate that cannot be fitted (too short a window, no valid start) just loses

    na_grid = NA_GRID if na is None else (na,)
    nb_grid = NB_GRID if nb is None else (nb,)
    delays = DELAY_GRID if delay is None else (delay,)
    # screen the delay with a mid-size model, then the orders at the best delay
    screen_na, screen_nb = (2 if na is None else na), (1 if nb is None else nb)
    for d in delays:
        run((screen_na, screen_nb, d))
    if not scored:
        raise ModelError(f"no candidate model could be fitted to the first {n} samples")
    best_delay = min(scored.values(), key=lambda cf: cf[0].bic)[0].delay
    for a, b in itertools.product(na_grid, nb_grid):
        run((a, b, best_delay))
    _retry_nested(uw, yw, scored, floor)
    ranked = sorted(scored.values(), key=lambda cf: cf[0].bic)
    chosen, fit = ranked[0]
    return OrderChoice(
        chosen=chosen, runner_up=ranked[1][0] if len(ranked) > 1 else None, window=n,
        candidates=tuple(c for c, _ in ranked), fixed=fixed, start=fit.model, delta0=fit.delta0,
    )  # fmt: skip
