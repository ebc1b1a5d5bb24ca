"""The backlash operator and the simulation loop of the pseudo-Wiener model.

These are the compiled kernels behind :func:`servoid.ident.models.simulate`; they
take plain arrays so that the estimator, the refinement and the drivers'
simulated plant all run the very same arithmetic.
"""

from __future__ import annotations

import numpy as np

from servoid.ident._jit import jit, jit_inline

__all__ = [
    "backlash_step",
    "simulate_kernel",
    "rest_kernel",
    "extended_kernel",
    "schur_stable",
    "schur_stable_in",
    "normal_equations_kernel",
    "ZONE_UP",
    "ZONE_DOWN",
    "ZONE_MEMORY",
]

#: Zone codes returned per sample by :func:`simulate_kernel`.
ZONE_UP = 1
ZONE_DOWN = -1
ZONE_MEMORY = 0


@jit
def backlash_step(x: float, x_prev: float, y_prev: float, m2: float, c1: float, c2: float) -> tuple[float, int]:
    """One step of the backlash of eqs (2)-(8) with ``m1 = 1``.

    Parameters
    ----------
    x, x_prev : float
        Input of the backlash now and one sample before.
    y_prev : float
        Output one sample before.
    m2, c1, c2 : float
        Down-line slope and the two dead zones.

    Returns
    -------
    y : float
        ``y(k)``: ``x - c1`` on the up line (rising ``x`` past ``y(k-1) + c1``,
        eq. 6), ``m2 (x + c2)`` on the down line (falling ``x`` below
        ``y(k-1)/m2 - c2``, eq. 7), else ``y(k-1)`` (the memory zone, eq. 8).
    zone : int
        ``ZONE_UP``, ``ZONE_DOWN`` or ``ZONE_MEMORY``: which of the three held.

    Notes
    -----
    The direction of motion picks the line: rising ``x`` can only reach the
    up line and falling ``x`` only the down line. Where the lines do not cross
    this equals eq. (8) exactly; beyond the crossing point (``m2 != 1``,
    large ``|x|``), where eq. (8) would have ``g1 = g2 = 1``, it keeps the
    output single-valued.
    """
    if x > x_prev:
        if x > y_prev + c1:
            return x - c1, ZONE_UP
    elif x < x_prev:
        if x < y_prev / m2 - c2:
            return m2 * (x + c2), ZONE_DOWN
    return y_prev, ZONE_MEMORY


@jit
def extended_kernel(
    a: np.ndarray,
    b: np.ndarray,
    delay: int,
    m2: float,
    c1: float,
    c2: float,
    saturation: float,
    dead_band: float,
    friction: float,
    u: np.ndarray,
    y0: float,
    x_out: np.ndarray,
    y_out: np.ndarray,
    zone_out: np.ndarray,
) -> None:
    """Free-run simulation of the extended model (the blocks of :mod:`servoid.ident.models.effects`).

    Per sample: the input blocks turn ``u`` into ``w`` (saturation, then dead
    band); the linear block computes
    ``x(k) = -sum a_i x(k-i) + sum b_j (w(k-d-j) - friction s(k-j))`` with
    ``s(k) = sign(x(k-1) - x(k-2))``; the backlash of
    :func:`backlash_step` gives ``y``. Inputs and
    ``x`` before the first sample are zero, the backlash output ``y0``.
    With ``saturation = inf``, ``dead_band = 0`` and ``friction = 0`` this is
    :func:`simulate_kernel` (which calls it so).
    """
    na = a.shape[0]
    nb = b.shape[0] - 1
    n = u.shape[0]
    shaped = saturation < np.inf or dead_band > 0.0
    # Only the effects in use get their arrays: the plain model (simulate_kernel)
    # then runs as fast as before the effects existed.
    w = np.empty(n if shaped else 0)
    s = np.zeros(n if friction != 0.0 else 0)
    x_prev = 0.0
    x_prev2 = 0.0
    y_prev = y0
    for k in range(n):
        if shaped:
            v = u[k]
            if v > saturation:
                v = saturation
            elif v < -saturation:
                v = -saturation
            if v > dead_band:
                v -= dead_band
            elif v < -dead_band:
                v += dead_band
            else:
                v = 0.0
            w[k] = v
        if friction != 0.0:
            if x_prev > x_prev2:
                s[k] = 1.0
            elif x_prev < x_prev2:
                s[k] = -1.0
        x = 0.0
        for i in range(1, na + 1):
            if k - i >= 0:
                x -= a[i - 1] * x_out[k - i]
        for j in range(nb + 1):
            idx = k - delay - j
            if idx >= 0:
                x += b[j] * (w[idx] if shaped else u[idx])
            if friction != 0.0 and k - j >= 0:
                x -= b[j] * friction * s[k - j]
        y, zone = backlash_step(x, x_prev, y_prev, m2, c1, c2)
        zone_out[k] = zone
        x_out[k] = x
        y_out[k] = y
        x_prev2 = x_prev
        x_prev = x
        y_prev = y


@jit
def simulate_kernel(
    a: np.ndarray,
    b: np.ndarray,
    delay: int,
    m2: float,
    c1: float,
    c2: float,
    u: np.ndarray,
    y0: float,
    x_out: np.ndarray,
    y_out: np.ndarray,
    zone_out: np.ndarray,
) -> None:
    """Free-run simulation of eq. (1) followed by :func:`backlash_step`.

    Inputs before the first sample and the initial ``x`` are zero; the
    backlash output before the first sample is ``y0``.
    Fills ``x_out``, ``y_out`` and ``zone_out`` (``ZONE_UP``, ``ZONE_DOWN``
    or ``ZONE_MEMORY``) in place.
    """
    extended_kernel(a, b, delay, m2, c1, c2, np.inf, 0.0, 0.0, u, y0, x_out, y_out, zone_out)


@jit
def rest_kernel(
    a: np.ndarray,
    b: np.ndarray,
    delay: int,
    m2: float,
    c1: float,
    c2: float,
    u: np.ndarray,
    y0: float,
    delta0: float,
    x_out: np.ndarray,
    y_out: np.ndarray,
    zone_out: np.ndarray,
) -> None:
    """Free-run simulation of eq. (1) and :func:`backlash_step` from a servo at rest.

    Before the first sample the linear block sits at its steady state
    ``x(-i) = x0 = y0 + delta0`` for every ``i``, held there by the input
    ``u(-j) = x0 / G(1)`` (``G(1) = sum b / (1 + sum a)``, the static gain);
    the backlash's memory is the first reading, ``y(-1) = y0``. ``delta0`` is
    where in the play the record starts: ``c1`` on the up line, ``-c2`` on
    the down line (``m2 = 1``), in between inside the play. With ``G(1) = 0``
    the input before the record is 0. Fills the outputs in place.
    """
    na = a.shape[0]
    nb = b.shape[0] - 1
    n = u.shape[0]
    den = 1.0
    for i in range(na):
        den += a[i]
    num = 0.0
    for j in range(nb + 1):
        num += b[j]
    x0 = y0 + delta0
    u_before = x0 * den / num if num != 0.0 else 0.0
    x_prev = x0
    y_prev = y0
    for k in range(n):
        x = 0.0
        for i in range(1, na + 1):
            x -= a[i - 1] * (x_out[k - i] if k - i >= 0 else x0)
        for j in range(nb + 1):
            idx = k - delay - j
            x += b[j] * (u[idx] if idx >= 0 else u_before)
        y, zone = backlash_step(x, x_prev, y_prev, m2, c1, c2)
        zone_out[k] = zone
        x_out[k] = x
        y_out[k] = y
        x_prev = x
        y_prev = y


@jit
def schur_stable(a: np.ndarray) -> bool:
    """Whether all roots of ``z^na + a_1 z^(na-1) + ... + a_na`` lie strictly inside the unit circle.

    The Schur-Cohn step-down recursion: O(na^2), no root finding, so it is
    cheap enough to run on every estimator update.
    """
    na = a.shape[0]
    buf = np.empty(2 * na + 1)
    buf[:na] = a
    return schur_stable_in(buf, 0, na, na)


@jit_inline
def schur_stable_in(buf: np.ndarray, at: int, na: int, poly: int) -> bool:
    """:func:`schur_stable` of ``buf[at : at + na]`` with ``buf[poly : poly + na + 1]`` as scratch.

    No allocation and no slice per call: the estimator checks every update
    with it, in its one buffer, and an allocation costs as much as the check.
    """
    buf[poly] = 1.0
    for i in range(na):
        buf[poly + i + 1] = buf[at + i]
    for m in range(na, 0, -1):
        k = buf[poly + m]
        if not abs(k) < 1.0:
            return False
        denom = 1.0 - k * k
        # the step-down poly[i] <- (poly[i] - k poly[m - i]) / denom, in place pair by pair
        for i in range(m // 2 + 1):
            j = m - i
            if i > j:
                break
            pi = buf[poly + i]
            pj = buf[poly + j]
            buf[poly + i] = (pi - k * pj) / denom
            if j != i:
                buf[poly + j] = (pj - k * pi) / denom
    return True


@jit
def normal_equations_kernel(
    a: np.ndarray,
    b: np.ndarray,
    m2: np.ndarray,
    c1: np.ndarray,
    c2: np.ndarray,
    h: np.ndarray,
    delay: int,
    u: np.ndarray,
    y: np.ndarray,
    keep: np.ndarray,
    y0: float,
    jtj: np.ndarray,
    jtr: np.ndarray,
) -> float:
    """Free-run simulations of ``K`` parameter sets in step, reduced to least-squares normal equations as they go.

    Row 0 of ``a`` (K x na), ``b`` (K x (nb + 1)), ``m2``, ``c1``, ``c2`` is
    the model at ``p``; row ``j + 1`` the model at ``p + h[j] e_j``. Per
    sample the residual ``r = y_hat_0 - y`` and the forward-difference
    Jacobian row ``J_j = (y_hat_(j+1) - y_hat_0) / h[j]`` are added into
    ``jtj += J^T J`` and ``jtr += J^T r`` (zeroed here) and never stored, so
    memory does not grow with the record (each model keeps its last ``na``
    values of ``x``). ``keep`` (empty: every sample) leaves samples out of
    the sums while the simulation runs through them. With ``K = 1`` it is
    the cost of one model. The arithmetic per model is :func:`simulate_kernel`'s.

    Returns
    -------
    float
        ``sum r^2`` over the kept samples; ``inf`` when a simulation is not finite.
    """
    k_models = a.shape[0]
    na = a.shape[1]
    nb = b.shape[1] - 1
    n_cols = h.shape[0]
    n = u.shape[0]
    use_keep = keep.shape[0] == n
    for i in range(n_cols):
        jtr[i] = 0.0
        for j in range(n_cols):
            jtj[i, j] = 0.0
    xh = np.zeros((k_models, na + 1))  # x(k-1) .. x(k-na) per model, newest first
    y_prev = np.full(k_models, y0)
    y_now = np.empty(k_models)
    row = np.empty(n_cols)
    cost = 0.0
    for k in range(n):
        for m in range(k_models):
            x = 0.0
            for i in range(na):
                x -= a[m, i] * xh[m, i]
            for j in range(nb + 1):
                idx = k - delay - j
                if idx >= 0:
                    x += b[m, j] * u[idx]
            yk, _ = backlash_step(x, xh[m, 0], y_prev[m], m2[m], c1[m], c2[m])  # xh[m, 0]: x(k-1)
            y_now[m] = yk
            y_prev[m] = yk
            for i in range(na - 1, 0, -1):
                xh[m, i] = xh[m, i - 1]
            xh[m, 0] = x
        if use_keep and not keep[k]:
            continue
        r = y_now[0] - y[k]
        cost += r * r
        for j in range(n_cols):
            row[j] = (y_now[j + 1] - y_now[0]) / h[j]
        for i in range(n_cols):
            jtr[i] += row[i] * r
            for j in range(i, n_cols):
                jtj[i, j] += row[i] * row[j]
    for i in range(n_cols):
        for j in range(i):
            jtj[i, j] = jtj[j, i]
    if not np.isfinite(cost):
        return np.inf
    for i in range(n_cols):
        if not np.isfinite(jtr[i]):
            return np.inf
    return cost
