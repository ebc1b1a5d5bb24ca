"""One step of the MRGIA, eqs (17)-(42), on a flat state vector.

The estimator's state, configuration, scratch and orders live in one
float64 buffer, the state at its start, so that an update from Python is one
call with one array and two floats (:func:`mrgia_update`), the cheapest call
numba offers, and nothing inside is sliced (:class:`StateLayout` names the
parts; :class:`servoid.ident.online.mrgia.MRGIA` exposes them as properties).
The step is compiled a second time for the default orders, as constants. The
readings of the paper's misprints follow ``shared/PAPER-NOTES.md`` and are
marked where they are used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from servoid.ident import defaults
from servoid.ident._jit import jit, jit_inline
from servoid.ident.models.kernels import schur_stable_in
from servoid.ident.models.pseudo_wiener import backlash_offset

_backlash_at = jit_inline(backlash_offset)

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
    "mrgia_update",
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

    @property
    def state(self) -> slice:
        """The state vector in the estimator's buffer: its start, so that state indices are buffer indices."""
        return slice(0, self.size)

    @property
    def cfg(self) -> slice:
        """The configuration vector (``CFG_*``) in the buffer."""
        return slice(self.size, self.size + CFG_SIZE)

    @property
    def work(self) -> slice:
        """The scratch of :func:`mrgia_step` in the buffer (:func:`work_size`)."""
        start = self.size + CFG_SIZE
        return slice(start, start + work_size(self.na, self.nb))

    @property
    def orders(self) -> slice:
        """``na, nb, d`` as floats, the buffer's last three entries (read by :func:`mrgia_update`)."""
        return slice(self.buffer_size - 3, self.buffer_size)

    @property
    def buffer_size(self) -> int:
        """Length of the estimator's one buffer: state, configuration, scratch, orders."""
        return self.size + CFG_SIZE + work_size(self.na, self.nb) + 3


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


_offsets = jit_inline(offsets)


def work_size(na: int, nb: int) -> int:
    """Length of the scratch vector :func:`mrgia_step` needs for these orders.

    ``h``, ``P h``, ``K``, the candidate theta, the candidate ``P``'s diagonal
    and the cap's scales (``n`` each; ``P`` itself is updated in place once
    the update is taken) and the stability test's polynomial (``na + 1``): kept by the
    caller, so that an update allocates nothing (an allocation costs as much
    as the arithmetic of a small model's update). Its contents between calls
    mean nothing.
    """
    n = na + nb + 4
    return 6 * n + na + 1


@jit_inline
def _feasible(buf: np.ndarray, at: int, na: int, nb: int, poly: int) -> bool:
    """For the candidate theta at ``buf[at:]``, the model's own assumptions: stable linear block, ``m2 > 0``, ``c1 >= 0``, ``c2 >= 0``.

    Zero dead zones are admitted because the paper starts from them (Section 4).

    The early updates from ``P(0) = 1e6 I`` are large. Without this check one
    of them can make the linear block unstable, ``x-hat`` then explodes,
    ``Sigma-hat`` follows (to ~1e23 in one seed of the paper's example) and
    the gain stays near zero for the rest of the run: a confident wrong model.
    Refusing such an update (a projection in the sense of Goodwin and Sin)
    keeps the estimate inside the set the model is defined on.
    """
    im2 = at + _backlash_at(na, nb)
    if not (1.0 + buf[im2] > 0.0 and buf[im2 + 1] >= 0.0 and buf[im2 + 2] >= 0.0):
        return False
    if na == 2:
        # the Schur-Cohn test of order 2 in closed form (the stability triangle), no division
        return bool(abs(buf[at + 1]) < 1.0 and abs(buf[at]) < 1.0 + buf[at + 1])
    return schur_stable_in(buf, at, na, poly)  # scratch at buf[poly:]


@jit_inline
def _neg_power(x: float, r: float) -> float:
    """``x^-r`` for rho(t) of eq. (30): by square roots for the exponents servoid uses (quarters), else ``pow``.

    A ``pow`` cost 16 % of an update; two square roots and a division cost
    a fraction of it, within an ulp or two of ``pow``.
    """
    if r == 0.75:
        sq = math.sqrt(x)
        return 1.0 / (sq * math.sqrt(sq))
    if r == 0.25:
        return 1.0 / math.sqrt(math.sqrt(x))
    if r == 0.5:
        return 1.0 / math.sqrt(x)
    if r == 1.0:
        return 1.0 / x
    return float(x ** (-r))


@jit_inline
def _predict_x(state: np.ndarray, na: int, nb: int, d: int, oxh: int, ouh: int) -> float:
    """Eq. (27): ``x-hat(k) = -sum a-hat_i x-hat(k-i) + sum b-hat_j u(k-d-j)`` with ``theta-hat(k-1)``."""
    xk = 0.0
    for i in range(na):
        xk -= state[i] * state[oxh + i]
    for j in range(nb + 1):
        xk += state[na + j] * state[ouh + d - 1 + j]  # the u history starts at u(k-1)
    return xk


@jit_inline
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


@jit_inline
def regressor(
    state: np.ndarray,
    na: int,
    nb: int,
    d: int,
    oxh: int,
    ouh: int,
    xk: float,
    up: float,
    down: float,
    h: np.ndarray,
    oh: int,
) -> None:
    """Fill ``h[oh : oh + n]`` with the regressor ``h-hat(k)`` of eq. (25), for a sample with ``Phi(k) = 1``.

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
        h[oh + i] = -state[oxh + i]  # eq. (25), read with the sign of (14)
    for j in range(nb + 1):
        h[oh + na + j] = state[ouh + d - 1 + j]
    h[oh + im2] = g3 * xk
    h[oh + im2 + 1] = -0.5 * mk * (sg + 1.0) * up  # eqs (25), (39)
    h[oh + im2 + 2] = 0.5 * mk * (-sg + 1.0) * down


@jit_inline
def _shift(hist: np.ndarray, start: int, length: int, value: float) -> None:
    for i in range(length - 1, 0, -1):
        hist[start + i] = hist[start + i - 1]
    if length > 0:
        hist[start] = value


@jit_inline
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


@jit_inline
def mrgia_step(state: np.ndarray, oc: int, ow: int, na: int, nb: int, d: int, u: float, y: float) -> int:
    """Process one sample ``(u(k), y(k))``; return a ``STEP_*`` code.

    ``state`` is the estimator's buffer (:class:`BufferLayout`): the state
    from 0, the configuration from ``oc`` and the scratch from ``ow``
    (nothing is allocated here, and nothing is sliced: a view costs a
    reference count, as much as a few multiplications). A non-finite ``u`` or
    ``y`` returns ``STEP_NOT_FINITE`` and changes nothing.

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
      loses positive definiteness from ``P(0) = 1e6 I``; its diagonal is
      computed first (it alone decides a divergence and the tracking cap),
      then ``P`` in place, only for an update that is taken;
    * eq. (18) read as ``theta(k) = theta(k-1) + K(k) Phi(k) e-hat(k)``, the
      form of the appendix's (50);
    * eq. (30): ``mu(k) = rho(t-1)/rho(t) (1 - rho(t))`` with
      ``rho(t) = (t + 1)^-r``, ``t = k + 1`` for the k-th sample, ``rho(0) = 1``.
    """
    if not (math.isfinite(u) and math.isfinite(y)):
        return STEP_NOT_FINITE
    n, op, ok, oxh, ouh, osc = _offsets(na, nb, d)
    r = state[oc + CFG_RHO_EXPONENT]
    eps = state[oc + CFG_EPSILON]
    # the scratch: h, P h, K, the candidate theta, P's candidate diagonal and scales, the stability test's polynomial
    oh = ow
    oph = ow + n
    okg = ow + 2 * n
    oth = ow + 3 * n
    opn = ow + 4 * n
    opoly = ow + 6 * n

    xk = _predict_x(state, na, nb, d, oxh, ouh)  # eq. (27)

    t = state[osc + SC_T] + 1.0  # this is sample k = t - 1
    code = STEP_PRIMED
    if state[osc + SC_PRIMED] != 0.0:
        up, down, g4, g5, dy = switching(state, na, nb, osc, xk, y, eps)  # eqs (32)-(38)
        phi = 1.0 if (up == 1.0 or down == 1.0) else 0.0  # eq. (42)

        code = STEP_HELD

        if phi == 1.0:
            regressor(state, na, nb, d, oxh, ouh, xk, up, down, state, oh)  # eq. (25)

            e = y  # eq. (41): y_c-hat(k) = y(k) when Phi = 1
            for i in range(n):
                e -= state[oh + i] * state[i]  # eq. (17)

            floor = state[oc + CFG_RHO_FLOOR]
            raw = _neg_power(t + 1.0, r)
            raw_prev = state[osc + SC_RHO] if state[osc + SC_RHO_AT] == t else _neg_power(t, r)
            rho = max(raw, floor)
            rho_prev = max(raw_prev, floor)
            mu = rho_prev / rho * (1.0 - rho)  # eq. (30); constant 1 - floor once at the floor
            sigma = state[osc + SC_SIGMA] + rho * (e * e - state[osc + SC_SIGMA])  # eq. (22)

            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += state[op + i * n + j] * state[oh + j]
                state[oph + i] = acc
            hph = 0.0
            for i in range(n):
                hph += state[oh + i] * state[oph + i]
            s = hph + mu * sigma  # eq. (19)
            if not (s > 0.0) or not math.isfinite(s):
                return STEP_DIVERGED
            inv_s = 1.0 / s  # one division, n multiplications
            for i in range(n):
                state[okg + i] = state[oph + i] * inv_s  # eq. (20)

            # eq. (21)'s diagonal first, into the scratch: it alone decides a divergence and the cap, so
            # that P itself is written in place, once, and only when the update is taken
            inv_mu = 1.0 / mu
            q = state[oc + CFG_PROCESS_NOISE]
            ok_flag = True
            for i in range(n):
                ki = state[okg + i]
                v = (state[op + i * n + i] - 2.0 * ki * state[oph + i] + hph * ki * ki) * inv_mu + sigma * ki * ki
                v += q  # tracking: parameters as a random walk of variance q per update
                state[opn + i] = v
                if not math.isfinite(v) or v <= 0.0:
                    ok_flag = False
            for i in range(n):
                state[oth + i] = state[i] + state[okg + i] * e  # eq. (18) as in (50)
                if not math.isfinite(state[oth + i]):
                    ok_flag = False
            if not ok_flag:
                return STEP_DIVERGED
            state[osc + SC_RHO] = raw  # after the divergence checks: a diverging sample changes nothing
            state[osc + SC_RHO_AT] = t + 1.0
            if state[oc + CFG_PROJECT] != 0.0 and not _feasible(state, oth, na, nb, opoly):
                code = STEP_REFUSED
            else:
                # tracking: cap P's diagonal by a congruence D P D with D diagonal, which keeps P
                # symmetric positive definite (unexcited directions would otherwise grow without bound
                # under forgetting); d_i = 1 for a diagonal element within the cap
                p_max = state[oc + CFG_P_MAX]
                for i in range(n):
                    pii = state[opn + i]
                    state[opn + n + i] = math.sqrt(p_max / pii) if pii > p_max else 1.0
                # eq. (21), Joseph form [I - K h^T] P [I - K h^T]^T / mu + K Sigma K^T, in place: each
                # P_ij is read once, before it is written; the upper triangle, mirrored
                for i in range(n):
                    ki = state[okg + i]
                    phi_i = state[oph + i]
                    di = state[opn + n + i]
                    state[op + i * n + i] = state[opn + i] * di * di
                    for j in range(i + 1, n):
                        kj = state[okg + j]
                        v = (state[op + i * n + j] - ki * state[oph + j] - phi_i * kj + hph * ki * kj) * inv_mu
                        v = (v + sigma * ki * kj) * (di * state[opn + n + j])
                        state[op + i * n + j] = v
                        state[op + j * n + i] = v
                for i in range(n):
                    state[i] = state[oth + i]
                    state[ok + i] = state[okg + i]
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
        alpha = state[oc + CFG_COVERAGE_ALPHA]
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
    below = state[oc + CFG_STUCK_BELOW]
    if below > 0.0 and state[osc + SC_SINCE_RESET] > state[oc + CFG_WARMUP]:
        # min(line_coverage) < below, multiplied out: no division per sample (a side that moved in too
        # few samples reports 1, never below the threshold)
        move_up = state[osc + SC_MOVE_UP]
        move_down = state[osc + SC_MOVE_DOWN]
        if (move_up > MIN_MOVE_SHARE and state[osc + SC_LINE_UP] < below * move_up) or (
            move_down > MIN_MOVE_SHARE and state[osc + SC_LINE_DOWN] < below * move_down
        ):
            code += STEP_STUCK
    return code


# The orders servoid runs by default, for which the step is compiled a second time with the orders
# and offsets as constants: its loops unroll and its indices fold (2.5 times faster on the
# paper's plant, the same numbers). Other orders run the general step.
_NA, _NB, _D = defaults.NA, defaults.NB, defaults.DELAY
_OC = offsets(_NA, _NB, _D)[5] + N_SCALARS


@jit
def mrgia_update(buf: np.ndarray, u: float, y: float) -> int:
    """:func:`mrgia_step` on an estimator's whole buffer (:class:`StateLayout`), its orders read from the buffer.

    The online estimator's calling convention: one array and two floats, the
    cheapest call into compiled code from Python (a call's cost grows with
    each argument numba has to convert, an array's most).
    """
    m = buf.shape[0]
    na = int(buf[m - 3])
    nb = int(buf[m - 2])
    d = int(buf[m - 1])
    if na == _NA and nb == _NB and d == _D:
        return mrgia_step(buf, _OC, _OC + CFG_SIZE, _NA, _NB, _D, u, y)  # the common orders, specialised
    oc = _offsets(na, nb, d)[5] + N_SCALARS
    return mrgia_step(buf, oc, oc + CFG_SIZE, na, nb, d, u, y)


@jit_inline
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
    buf: np.ndarray,
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
) -> tuple[int, int]:
    """Run :func:`mrgia_step` over whole arrays, on an estimator's buffer (:class:`StateLayout`).

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
    oc = osc + N_SCALARS
    ow = oc + CFG_SIZE
    code = 0
    special = na == _NA and nb == _NB and d == _D
    left = record_every - row0 % record_every  # samples to the next recorded one: no division per sample
    for k in range(n_samples):
        if valid[k]:
            if special:
                code = mrgia_step(buf, _OC, _OC + CFG_SIZE, _NA, _NB, _D, u[k], y[k])  # constants: see _NA
            else:
                code = mrgia_step(buf, oc, ow, na, nb, d, u[k], y[k])
            if code == STEP_DIVERGED:
                return 2, k
        else:
            mrgia_skip(buf, na, nb, d, u[k])
            code = 0
        left -= 1
        if left == 0:
            left = record_every
            row = (row0 + k + 1) // record_every - 1
            cov_up, cov_down = line_coverage(buf, na, nb, d)
            for i in range(n):
                theta_out[row, i] = buf[i]
            coverage_out[row, 0] = cov_up
            coverage_out[row, 1] = cov_down
        if code >= STEP_STUCK:
            return 1, k
    return 0, n_samples
