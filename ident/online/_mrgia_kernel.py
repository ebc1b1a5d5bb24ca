"""One step of the MRGIA, eqs (17)-(42), on a flat state vector.

The estimator's whole state lives in one float64 array so that a compiled
step costs one call with three arguments (:class:`StateLayout` names the
slices; :class:`servoid.ident.online.mrgia.MRGIA` exposes them as properties). The
readings of the paper's misprints follow ``shared/PAPER-NOTES.md`` and are
marked where they are used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from servoid.ident._jit import jit
from servoid.ident.models.kernels import schur_stable_in
from servoid.ident.models.pseudo_wiener import backlash_offset

_backlash_at = jit(backlash_offset)

__all__ = [
    "StateLayout",
    "CFG_RHO_EXPONENT",
    "CFG_EPSILON",
    "CFG_COVERAGE_ALPHA",
    "MIN_MOVE_SHARE",
    "CFG_PROJECT",
    "CFG_STUCK_BELOW",
    "CFG_WARMUP",
    "CFG_RHO_FLOOR",
    "CFG_PROCESS_NOISE",
    "CFG_P_MAX",
    "STEP_STUCK",
    "mrgia_recover",
    "CFG_SIZE",
    "STEP_REFUSED",
    "STEP_PRIMED",
    "STEP_HELD",
    "STEP_UPDATED",
    "STEP_DIVERGED",
    "STEP_NOT_FINITE",
    "work_size",
    "mrgia_step",
    "mrgia_skip",
    "line_coverage",
    "mrgia_run",
]

# configuration vector
CFG_RHO_EXPONENT = 0
CFG_EPSILON = 1
CFG_COVERAGE_ALPHA = 2
CFG_PROJECT = 3  # 1: refuse updates that leave the feasible set (see _feasible)
CFG_STUCK_BELOW = 4  # a line coverage below this after the warm-up flags the run as stuck (0: never)
CFG_WARMUP = 5  # samples after a start or a recovery before the coverage is judged
CFG_RHO_FLOOR = 6  # tracking: rho(t) never falls below this (0: the paper's rho)
CFG_PROCESS_NOISE = 7  # tracking: q added to P's diagonal at each update (random-walk parameters)
CFG_P_MAX = 8  # tracking: cap on P's diagonal elements (inf: none)
CFG_SIZE = 9

# scalar slots, after the arrays (offsets relative to StateLayout.scalars)
SC_S = 0  # S(k), eq. (19)
SC_SIGMA = 1  # Sigma-hat(k), eq. (22)
SC_Y_PREV = 2  # y(k-1), measured
SC_T = 3  # samples seen so far; the k-th sample (0-based) uses rho(t) with t = k + 1
SC_PRIMED = 4  # 1 once y(k-1) is known
SC_ERROR = 5  # e-hat(k) of the last update, eq. (17)
SC_PHI = 6  # Phi(k) of the last sample, eq. (42)
SC_UPDATES = 7  # number of samples with Phi = 1
SC_X = 8  # x-hat(k) of the last sample
# Exponentially weighted shares of samples (window 1/alpha) in which the output
# measurably moved up (g4) or down (g5), and in which the model updated on the
# up line (g1 g4) or the down line (g2 g5). A run stuck in a wrong zone
# classification starves one line: the output moves that way but the model
# never puts a sample on that line, so its parameters are never corrected.
SC_MOVE_UP = 9
SC_MOVE_DOWN = 10
SC_LINE_UP = 11
SC_LINE_DOWN = 12
SC_SINCE_RESET = 13  # samples since the start or the last recovery
# rho(t) of eq. (30) without the floor, and its t: the next update's rho(t-1) is usually this one,
# which saves one of its two powers (the costliest operations of an update)
SC_RHO = 14
SC_RHO_AT = 15
N_SCALARS = 16

#: Below this share of samples moving one way, that side is not judged.
MIN_MOVE_SHARE = 0.02

#: A measured move counts for the line coverage when |dy| >= this times epsilon.
COVERAGE_MOVE_FACTOR = 6.0

# return codes of mrgia_step
STEP_PRIMED = 0  # first sample after start or a gap: y(k-1) unknown, nothing estimated
STEP_HELD = 1  # Phi = 0: memory zone, nothing updated (eq. 42)
STEP_UPDATED = 2  # Phi = 1: theta, P, S, K, Sigma updated
STEP_DIVERGED = 3  # theta or P became non-finite; the state is left as it was before the step
STEP_REFUSED = 4  # Phi = 1 but the update would leave the feasible set: nothing updated
STEP_NOT_FINITE = 5  # u or y is not finite: nothing changed
STEP_STUCK = 8  # flag added to the code: past the warm-up, a line coverage is below CFG_STUCK_BELOW


@dataclass(frozen=True)
class StateLayout:
    """Where each part of the MRGIA state sits in the flat state vector.

    Parameters
    ----------
    na, nb, delay : int
        Model orders and input delay.
    """

    na: int
    nb: int
    delay: int

    def _at(self) -> tuple[int, int, int, int, int, int]:
        return offsets(self.na, self.nb, self.delay)

    @property
    def n(self) -> int:
        """Number of parameters, ``na + nb + 4`` (eq. 15)."""
        return self._at()[0]

    @property
    def theta(self) -> slice:
        """``theta-hat(k)`` (eq. 24), in the layout of :class:`~servoid.ident.models.pseudo_wiener.ThetaLayout`."""
        return slice(0, self.n)

    @property
    def P(self) -> slice:
        """``P(k)`` row by row (eq. 21)."""
        n, op = self._at()[:2]
        return slice(op, op + n * n)

    @property
    def K(self) -> slice:
        """``K(k)`` (eq. 20)."""
        n, _, ok = self._at()[:3]
        return slice(ok, ok + n)

    @property
    def x_history(self) -> slice:
        """``x-hat(k-1) .. x-hat(k-na)``, newest first."""
        oxh = self._at()[3]
        return slice(oxh, oxh + self.na)

    @property
    def u_history(self) -> slice:
        """``u(k-1) .. u(k-d-nb)``, newest first."""
        ouh = self._at()[4]
        return slice(ouh, ouh + self.delay + self.nb)

    @property
    def scalars(self) -> int:
        """Offset of the scalar slots ``SC_*``."""
        return self._at()[5]

    @property
    def size(self) -> int:
        """Length of the whole state vector."""
        return self.scalars + N_SCALARS


def offsets(na: int, nb: int, d: int) -> tuple[int, int, int, int, int, int]:
    """``(n, P, K, x history, u history, scalars)``: the length of theta and where each part starts.

    The one place for the layout: the compiled kernels call it (as ``_offsets``)
    and :class:`StateLayout` names its slices for Python.
    """
    n = na + nb + 4
    p = n
    kk = p + n * n
    xh = kk + n
    uh = xh + na
    sc = uh + d + nb
    return n, p, kk, xh, uh, sc


_offsets = jit(offsets)


def work_size(na: int, nb: int) -> int:
    """Length of the scratch vector :func:`mrgia_step` needs for these orders.

    ``h``, ``P h``, ``K``, the candidate theta (``n`` each), the candidate ``P``
    (``n^2``) and the stability test's polynomial (``na + 1``): kept by the
    caller, so that an update allocates nothing (an allocation costs as much
    as the arithmetic of a small model's update). Its contents between calls
    mean nothing.
    """
    n = na + nb + 4
    return 4 * n + n * n + na + 1


@jit
def _feasible(theta: np.ndarray, na: int, nb: int, poly: np.ndarray) -> bool:
    """The model's own assumptions: stable linear block, ``m2 > 0``, ``c1 >= 0``, ``c2 >= 0``.

    Zero dead zones are admitted because the paper starts from them (Section 4).

    The early updates from ``P(0) = 1e6 I`` are large. Without this check one
    of them can make the linear block unstable, ``x-hat`` then explodes,
    ``Sigma-hat`` follows (to ~1e23 in one seed of the paper's example) and
    the gain stays near zero for the rest of the run: a confident wrong model.
    Refusing such an update (a projection in the sense of Goodwin and Sin)
    keeps the estimate inside the set the model is defined on.
    """
    im2 = _backlash_at(na, nb)
    if not (1.0 + theta[im2] > 0.0 and theta[im2 + 1] >= 0.0 and theta[im2 + 2] >= 0.0):
        return False
    return schur_stable_in(theta[:na], poly)


@jit
def _predict_x(state: np.ndarray, na: int, nb: int, d: int, oxh: int, ouh: int) -> float:
    """Eq. (27): ``x-hat(k) = -sum a-hat_i x-hat(k-i) + sum b-hat_j u(k-d-j)`` with ``theta-hat(k-1)``."""
    xk = 0.0
    for i in range(na):
        xk -= state[i] * state[oxh + i]
    for j in range(nb + 1):
        xk += state[na + j] * state[ouh + d - 1 + j]  # the u history starts at u(k-1)
    return xk


@jit
def switching(
    state: np.ndarray, na: int, nb: int, osc: int, xk: float, y: float, eps: float
) -> tuple[float, float, float, float, float]:
    """The switching functions for the sample ``y(k)``: ``(g1 g4, g2 g5, g4, g5, dy)``.

    Eqs (32), (33) with ``theta-hat(k-1)`` and the measured ``y(k-1)`` (eq. 32
    read as ``y(k-1)/m1 + c1`` with ``m1 = 1``); eqs (35)-(38) from the
    measured change ``dy`` of ``y`` with the threshold ``epsilon``
    (``epsilon = 0`` gives 35, 36). ``Phi(k) = 1`` (eq. 42) iff one of the two
    products is 1.
    """
    im2 = _backlash_at(na, nb)
    m2h = 1.0 + state[im2]
    y_prev = state[osc + SC_Y_PREV]
    g1 = 1.0 if y_prev + state[im2 + 1] < xk else 0.0  # eq. (32), m1 = 1
    g2 = 1.0 if y_prev / m2h - state[im2 + 2] > xk else 0.0  # eq. (33)
    dy = y - y_prev
    g4 = 1.0 if (dy > 0.0 and dy >= eps) else 0.0  # eqs (35), (37)
    g5 = 1.0 if (-dy > 0.0 and -dy >= eps) else 0.0  # eqs (36), (38)
    return g1 * g4, g2 * g5, g4, g5, dy


@jit
def regressor(
    state: np.ndarray, na: int, nb: int, d: int, oxh: int, ouh: int, xk: float, up: float, down: float, h: np.ndarray
) -> None:
    """Fill ``h`` with the regressor ``h-hat(k)`` of eq. (25), for a sample with ``Phi(k) = 1``.

    Read with ``-x-hat(k-i)`` entries as in (14), with ``u(k-d-nb)`` and
    ``g3-hat x-hat(k)`` as two entries, and with the ``g4``/``g5`` products of
    eqs (39)-(41) in the dead-zone entries; ``g3`` and ``m`` by eqs (34), (26).
    """
    dx = xk - state[oxh]
    g3 = 1.0 if dx < 0.0 else 0.0  # eq. (34)
    im2 = _backlash_at(na, nb)
    mk = 1.0 + ((1.0 + state[im2]) - 1.0) * g3  # eq. (26) with m2-hat = 1 + theta (kept as printed: bit for bit)
    sg = 1.0 if dx > 0.0 else (-1.0 if dx < 0.0 else 0.0)
    for i in range(na):
        h[i] = -state[oxh + i]  # eq. (25), read with the sign of (14)
    for j in range(nb + 1):
        h[na + j] = state[ouh + d - 1 + j]
    h[im2] = g3 * xk
    h[im2 + 1] = -0.5 * mk * (sg + 1.0) * up  # eqs (25), (39)
    h[im2 + 2] = 0.5 * mk * (-sg + 1.0) * down


@jit
def _shift(hist: np.ndarray, start: int, length: int, value: float) -> None:
    for i in range(length - 1, 0, -1):
        hist[start + i] = hist[start + i - 1]
    if length > 0:
        hist[start] = value


@jit
def line_coverage(state: np.ndarray, na: int, nb: int, d: int) -> tuple[float, float]:
    """Share of measured moves up / down that the model put on the up / down line.

    Returns ``(up, down)``; a side whose output moved in fewer than
    ``MIN_MOVE_SHARE`` of the recent samples reports 1 (nothing to judge).
    Both tend to 1 as the zone classification settles; a run stuck in a wrong
    classification keeps one of them near 0.
    """
    osc = _offsets(na, nb, d)[5]
    up = 1.0
    down = 1.0
    if state[osc + SC_MOVE_UP] > MIN_MOVE_SHARE:
        up = state[osc + SC_LINE_UP] / state[osc + SC_MOVE_UP]
    if state[osc + SC_MOVE_DOWN] > MIN_MOVE_SHARE:
        down = state[osc + SC_LINE_DOWN] / state[osc + SC_MOVE_DOWN]
    return up, down


@jit
def mrgia_step(
    state: np.ndarray, cfg: np.ndarray, work: np.ndarray, na: int, nb: int, d: int, u: float, y: float
) -> int:
    """Process one sample ``(u(k), y(k))``; return a ``STEP_*`` code.

    ``work`` is scratch of length :func:`work_size` (nothing is allocated here);
    a non-finite ``u`` or ``y`` returns ``STEP_NOT_FINITE`` and changes nothing.

    Notes
    -----
    Implements, in this order:

    * eq. (27): ``x-hat(k)`` from the stored ``x-hat`` history and the inputs
      ``u(k-d-j)``, with ``theta-hat(k-1)`` (:func:`_predict_x`);
    * eqs (32)-(38): the switching functions (:func:`switching`);
    * eq. (42): ``Phi(k) = 1`` iff ``g1 g4 = 1`` or ``g2 g5 = 1``;
    * eqs (34), (26), (25) with the ``g4``/``g5`` products of eqs (39)-(41): the
      regressor ``h-hat(k)`` (:func:`regressor`);
    * eq. (41): when ``Phi = 1`` the switching product is zero, so
      ``y_c-hat(k) = y(k)`` (eq. 28's ``y1-hat`` only matters when ``Phi = 0``,
      when nothing is updated);
    * eq. (17): ``e-hat(k) = y_c-hat(k) - h-hat(k)^T theta-hat(k-1)``;
    * eq. (22) first, then (19), (20), (21), (18): ``Sigma-hat(k)``, ``S(k)``,
      ``K(k)``, ``P(k)``, ``theta-hat(k)`` (Sigma-hat(k) is used by the others);
    * eq. (21) in Joseph form ``[I - K h^T] P [I - K h^T]^T / mu + K Sigma K^T``,
      evaluated in O(n^2) from ``P h`` and mirrored so that P stays exactly
      symmetric: the algebraically equal short form ``(P - K h^T P)/mu``
      loses positive definiteness from ``P(0) = 1e6 I``;
    * eq. (18) read as ``theta(k) = theta(k-1) + K(k) Phi(k) e-hat(k)``, the
      form of the appendix's (50);
    * eq. (30): ``mu(k) = rho(t-1)/rho(t) (1 - rho(t))`` with
      ``rho(t) = (t + 1)^-r``, ``t = k + 1`` for the k-th sample, ``rho(0) = 1``.
    """
    if not (math.isfinite(u) and math.isfinite(y)):
        return STEP_NOT_FINITE
    n, op, ok, oxh, ouh, osc = _offsets(na, nb, d)
    r = cfg[CFG_RHO_EXPONENT]
    eps = cfg[CFG_EPSILON]
    h = work[:n]
    ph = work[n : 2 * n]
    kg = work[2 * n : 3 * n]
    theta_new = work[3 * n : 4 * n]
    p_new = work[4 * n : 4 * n + n * n]
    poly = work[4 * n + n * n : 4 * n + n * n + na + 1]

    xk = _predict_x(state, na, nb, d, oxh, ouh)  # eq. (27)

    t = state[osc + SC_T] + 1.0  # this is sample k = t - 1
    code = STEP_PRIMED
    if state[osc + SC_PRIMED] != 0.0:
        up, down, g4, g5, dy = switching(state, na, nb, osc, xk, y, eps)  # eqs (32)-(38)
        phi = 1.0 if (up == 1.0 or down == 1.0) else 0.0  # eq. (42)

        code = STEP_HELD

        if phi == 1.0:
            regressor(state, na, nb, d, oxh, ouh, xk, up, down, h)  # eq. (25)

            e = y  # eq. (41): y_c-hat(k) = y(k) when Phi = 1
            for i in range(n):
                e -= h[i] * state[i]  # eq. (17)

            floor = cfg[CFG_RHO_FLOOR]
            raw = (t + 1.0) ** (-r)
            raw_prev = state[osc + SC_RHO] if state[osc + SC_RHO_AT] == t else t ** (-r)
            rho = max(raw, floor)
            rho_prev = max(raw_prev, floor)
            mu = rho_prev / rho * (1.0 - rho)  # eq. (30); constant 1 - floor once at the floor
            sigma = state[osc + SC_SIGMA] + rho * (e * e - state[osc + SC_SIGMA])  # eq. (22)

            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += state[op + i * n + j] * h[j]
                ph[i] = acc
            hph = 0.0
            for i in range(n):
                hph += h[i] * ph[i]
            s = hph + mu * sigma  # eq. (19)
            if not (s > 0.0) or not math.isfinite(s):
                return STEP_DIVERGED
            for i in range(n):
                kg[i] = ph[i] / s  # eq. (20)

            # eq. (21), Joseph form, upper triangle then mirrored
            q = cfg[CFG_PROCESS_NOISE]
            for i in range(n):
                for j in range(i, n):
                    v = (state[op + i * n + j] - kg[i] * ph[j] - ph[i] * kg[j] + hph * kg[i] * kg[j]) / mu + sigma * kg[
                        i
                    ] * kg[j]
                    if i == j:
                        v += q  # tracking: parameters as a random walk of variance q per update
                    p_new[i * n + j] = v
                    p_new[j * n + i] = v
            # tracking: cap P's diagonal by a congruence D P D with D diagonal,
            # which keeps P symmetric positive definite (unexcited directions
            # would otherwise grow without bound under forgetting)
            p_max = cfg[CFG_P_MAX]
            for i in range(n):
                pii = p_new[i * n + i]
                if pii > p_max:
                    sc = math.sqrt(p_max / pii)
                    for j in range(n):
                        p_new[i * n + j] *= sc
                        p_new[j * n + i] *= sc
            ok_flag = True
            for i in range(n):
                if not math.isfinite(p_new[i * n + i]) or p_new[i * n + i] <= 0.0:
                    ok_flag = False
            for i in range(n):
                theta_new[i] = state[i] + kg[i] * e  # eq. (18) as in (50)
                if not math.isfinite(theta_new[i]):
                    ok_flag = False
            if not ok_flag:
                return STEP_DIVERGED
            state[osc + SC_RHO] = raw  # after the divergence checks: a diverging sample changes nothing
            state[osc + SC_RHO_AT] = t + 1.0
            if cfg[CFG_PROJECT] != 0.0 and not _feasible(theta_new, na, nb, poly):
                code = STEP_REFUSED
            else:
                for i in range(n):
                    state[i] = theta_new[i]
                    state[ok + i] = kg[i]
                for i in range(n * n):
                    state[op + i] = p_new[i]
                state[osc + SC_S] = s
                state[osc + SC_SIGMA] = sigma
                state[osc + SC_ERROR] = e
                state[osc + SC_UPDATES] += 1.0
                code = STEP_UPDATED

        # after the divergence checks, so that a diverging sample changes nothing
        # Coverage counts only clear moves, |dy| >= 6 epsilon (~5 noise std):
        # with output noise about half the samples in the play cross epsilon
        # itself (9 % cross 3 epsilon) and the model rightly keeps them off the
        # lines; counting them made a long one-sided stretch look stuck.
        alpha = cfg[CFG_COVERAGE_ALPHA]
        clear = COVERAGE_MOVE_FACTOR * eps
        move_up = 1.0 if (g4 == 1.0 and dy >= clear) else 0.0
        move_down = 1.0 if (g5 == 1.0 and -dy >= clear) else 0.0
        state[osc + SC_MOVE_UP] += alpha * (move_up - state[osc + SC_MOVE_UP])
        state[osc + SC_MOVE_DOWN] += alpha * (move_down - state[osc + SC_MOVE_DOWN])
        state[osc + SC_LINE_UP] += alpha * (up * move_up - state[osc + SC_LINE_UP])
        state[osc + SC_LINE_DOWN] += alpha * (down * move_down - state[osc + SC_LINE_DOWN])
        state[osc + SC_PHI] = phi

    # advance: x-hat(k) (computed with theta-hat(k-1)), u(k), y(k), t
    _shift(state, oxh, na, xk)
    _shift(state, ouh, d + nb, u)
    state[osc + SC_X] = xk
    state[osc + SC_Y_PREV] = y
    state[osc + SC_PRIMED] = 1.0
    state[osc + SC_T] = t
    state[osc + SC_SINCE_RESET] += 1.0
    if cfg[CFG_STUCK_BELOW] > 0.0 and state[osc + SC_SINCE_RESET] > cfg[CFG_WARMUP]:
        cov_up, cov_down = line_coverage(state, na, nb, d)
        if min(cov_up, cov_down) < cfg[CFG_STUCK_BELOW]:
            code += STEP_STUCK
    return code


@jit
def mrgia_skip(state: np.ndarray, na: int, nb: int, d: int, u: float) -> None:
    """Advance over a sample whose measurement was lost.

    ``x-hat(k)`` is propagated with the commanded ``u`` (the plant moved even
    if we did not see it), nothing is estimated, and the next sample only
    primes ``y(k-1)``: a change of ``y`` across the gap is not a one-sample
    change and must not drive ``g4``/``g5``.
    """
    n, op, ok, oxh, ouh, osc = _offsets(na, nb, d)
    xk = _predict_x(state, na, nb, d, oxh, ouh)  # eq. (27)
    _shift(state, oxh, na, xk)
    _shift(state, ouh, d + nb, u)
    state[osc + SC_X] = xk
    state[osc + SC_PRIMED] = 0.0
    state[osc + SC_T] = state[osc + SC_T] + 1.0


@jit
def mrgia_recover(state: np.ndarray, na: int, nb: int, d: int, theta0: np.ndarray, p0: float, sigma0: float) -> None:
    """Recover from a stuck zone classification (servoid's addition to the paper).

    The backlash parameters ``m2 - 1``, ``c1``, ``c2`` return to their values
    in ``theta0``, ``P`` to ``p0 I`` and ``Sigma-hat`` to ``sigma0``; the
    linear block and the ``x-hat`` history are kept. In every stuck run of the
    paper's example the linear block had converged while a wrong dead zone kept
    the model off one line (its samples never updated), so this re-opens that
    line without discarding what was learned.
    """
    n, op, ok, oxh, ouh, osc = _offsets(na, nb, d)
    for i in range(_backlash_at(na, nb), n):
        state[i] = theta0[i]
    for i in range(n):
        for j in range(n):
            state[op + i * n + j] = p0 if i == j else 0.0
    state[osc + SC_SIGMA] = sigma0
    state[osc + SC_MOVE_UP] = 0.0
    state[osc + SC_MOVE_DOWN] = 0.0
    state[osc + SC_LINE_UP] = 0.0
    state[osc + SC_LINE_DOWN] = 0.0
    state[osc + SC_SINCE_RESET] = 0.0


@jit
def mrgia_run(
    state: np.ndarray,
    cfg: np.ndarray,
    na: int,
    nb: int,
    d: int,
    u: np.ndarray,
    y: np.ndarray,
    valid: np.ndarray,
    theta_out: np.ndarray,
    coverage_out: np.ndarray,
    record_every: int,
    row0: int,
    work: np.ndarray,
) -> tuple[int, int]:
    """Run :func:`mrgia_step` over whole arrays.

    Parameters
    ----------
    valid : ndarray of bool
        ``False`` where the measurement was lost (:func:`mrgia_skip`).
    theta_out, coverage_out : ndarray
        Row ``(row0 + k + 1) // record_every - 1`` receives theta and the two
        line coverages (:func:`line_coverage`) after sample ``k`` whenever
        ``row0 + k + 1`` is a multiple of ``record_every`` (``row0`` is the
        index of ``u[0]`` in the whole record, for runs resumed after a stop).

    Returns
    -------
    (status, k) : tuple of int
        ``(0, n)`` when all samples ran; ``(1, k)`` when sample ``k`` was
        processed and flagged ``STEP_STUCK`` (the caller recovers and resumes
        at ``k + 1``); ``(2, k)`` when sample ``k`` diverged (not processed).
    """
    n_samples = u.shape[0]
    n, op, ok, oxh, ouh, osc = _offsets(na, nb, d)
    code = 0
    for k in range(n_samples):
        if valid[k]:
            code = mrgia_step(state, cfg, work, na, nb, d, u[k], y[k])
            if code == STEP_DIVERGED:
                return 2, k
        else:
            mrgia_skip(state, na, nb, d, u[k])
            code = 0
        done = row0 + k + 1
        if done % record_every == 0:
            row = done // record_every - 1
            cov_up, cov_down = line_coverage(state, na, nb, d)
            for i in range(n):
                theta_out[row, i] = state[i]
            coverage_out[row, 0] = cov_up
            coverage_out[row, 1] = cov_down
        if code >= STEP_STUCK:
            return 1, k
    return 0, n_samples
