"""Offline output-error refinement of a backlash model (servoid's addition to the paper).

The MRGIA is an online method: its estimate is a good start, not the end.
Given a whole record, :func:`refine` minimises the simulation error
``sum (y - y_hat(theta))^2`` of the free-run model over all its parameters
with :func:`scipy.optimize.least_squares`, starting from a given model
(usually the MRGIA estimate), and returns standard errors from the Jacobian at
the optimum. On the paper's example at SNR 43 this takes the maximum relative
parameter error from ~4e-3 (MRGIA) to ~1e-3 at 5000 samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.metrics import residual_nrmse
from servoid.ident.models.kernels import rest_kernel, simulate_kernel
from servoid.ident.models.pseudo_wiener import BacklashModel, ThetaLayout, within_stability_margin
from servoid.ident.offline import _threads
from servoid.ident.offline._oefit import covariance_from_jacobian, failure_level, fit_output_error, fit_record

__all__ = ["Refinement", "refine", "output_error_jacobian", "arx_start"]

#: Smallest dead zone and down-line slope the search may reach, relative to std(y).
_LOWER_BOUND_REL = 1e-9


@dataclass(frozen=True)
class Refinement:
    """Result of :func:`refine`.

    Attributes
    ----------
    model : BacklashModel
        The refined model.
    initial : BacklashModel
        Where the search started.
    stderr : tuple of float
        Standard error of each parameter, in the order of ``model.names``
        (``m2`` itself, not ``m2 - 1``); NaN where the data do not determine it.
    covariance : ndarray
        Their covariance matrix ``s^2 (J^T J)^-1`` (over the fitted vector:
        the model's values, then ``delta0`` when the initial state was fitted;
        without ``c2`` when the play was held).
    nrmse, initial_nrmse : float
        Free-run NRMSE of the refined and of the initial model on the record.
    residual_std : float
        Standard deviation of ``y - y_hat`` at the optimum (an estimate of the noise).
    nfev : int
        Number of simulations of the model used by the search.
    success : bool
        Whether the optimiser reported convergence.
    message : str
        The optimiser's message.
    delta0 : float
        Where in the play the record starts (:func:`servoid.ident.models.kernels.rest_kernel`);
        0 when the initial state was not fitted (the simulation then starts at ``x = 0``).
    initial_state : bool
        Whether the simulation starts from rest with ``delta0`` fitted (else from ``x = 0``).
    residual : ndarray
        ``y_hat - y`` at the optimum, on the samples fitted.
    jacobian : ndarray
        The residual's Jacobian there, one column per fitted parameter (see ``covariance``).
    sse : float
        ``sum(residual^2)``.
    """

    model: BacklashModel
    initial: BacklashModel
    stderr: tuple[float, ...]
    covariance: np.ndarray
    nrmse: float
    initial_nrmse: float
    residual_std: float
    nfev: int
    success: bool
    message: str
    delta0: float = 0.0
    initial_state: bool = False
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    jacobian: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    sse: float = 0.0

    def __repr__(self) -> str:
        how = "converged" if self.success else f"did not converge: {self.message}"
        return (
            f"Refinement(NRMSE {self.nrmse:.4g} from {self.initial_nrmse:.4g}, {self.nfev} simulations, {how}; "
            f"{self.model!r})"
        )

    def stderr_dict(self) -> dict[str, float]:
        """``{name: standard error}`` for every parameter."""
        return dict(zip(self.model.names, self.stderr))

    def play_gradient(self) -> np.ndarray:
        """The gradient of ``c1 + c2`` in the fitted vector (for its standard error from :attr:`jacobian`)."""
        grad = np.zeros(self.jacobian.shape[1])
        lay = self.model.layout
        grad[lay.c1] = 1.0
        if lay.c2 < grad.size - int(self.initial_state):
            grad[lay.c2] = 1.0
        return grad

    def to_dict(self) -> dict[str, Any]:
        """For JSON: the model, its standard errors (null where the data do not determine one), the fit, the search."""
        return {
            "model": self.model.to_dict(), "stderr": self.stderr_dict(), "nrmse": self.nrmse,
            "initial_nrmse": self.initial_nrmse, "residual_std": self.residual_std, "nfev": self.nfev,
            "success": self.success, "message": self.message, "delta0": self.delta0,
        }  # fmt: skip


class _OutputError:
    """Residual ``y_hat(p) - y`` of the free-run model, for the optimiser.

    The vector ``p`` holds the model's values (``m2`` itself), without ``c2``
    when the play ``c1 + c2`` is held (``c2 = play - c1``), then ``delta0``
    when the simulation starts from rest.
    """

    def __init__(
        self,
        u: np.ndarray,
        y: np.ndarray,
        template: BacklashModel,
        y0: float,
        valid: np.ndarray | None = None,
        *,
        initial_state: bool = False,
        play: float | None = None,
    ) -> None:
        self.u, self.y, self.y0 = u, y, y0
        # lost samples (valid False) are simulated through but left out of the residual
        self.keep = valid
        self.na, self.nb, self.delay = template.na, template.nb, template.delay
        self.initial_state = initial_state
        self.play = play
        self.x = np.empty_like(u)
        self.y_hat = np.empty_like(u)
        self.zone = np.empty(u.shape, dtype=np.int8)
        # Outside the stable region the simulation explodes.
        self.y_used = y if valid is None else y[valid]
        self.failure = failure_level(self.y_used)  # the residual's value there, built only when needed

    def full(self, p: np.ndarray) -> tuple[np.ndarray, float]:
        """The model's values (``c2`` restored) and ``delta0`` from a fitted vector."""
        lay = ThetaLayout(self.na, self.nb)
        values = p[: p.size - 1] if self.initial_state else p
        delta0 = float(p[-1]) if self.initial_state else 0.0
        if self.play is not None:
            values = np.concatenate((values[: lay.c2], [self.play - values[lay.c1]]))
        return values, delta0

    def pack(self, values: np.ndarray, delta0: float) -> np.ndarray:
        """Inverse of :meth:`full`."""
        lay = ThetaLayout(self.na, self.nb)
        p = values[: lay.c2] if self.play is not None else values
        return np.concatenate((p, [delta0])) if self.initial_state else np.array(p, dtype=np.float64)

    def split(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float, float, float]:
        values, delta0 = self.full(p)
        lay = ThetaLayout(self.na, self.nb)
        return values[lay.a], values[lay.b], float(values[lay.m2]), float(values[lay.c1]), float(values[lay.c2]), delta0

    def simulate(self, p: np.ndarray) -> bool:
        """Fill :attr:`y_hat` for ``p``; False where the model is not valid (unstable, negative dead zone)."""
        a, b, m2, c1, c2, delta0 = self.split(p)
        if not within_stability_margin(a) or c2 <= 0.0:  # what BacklashModel accepts, no more
            return False
        a_c, b_c = np.ascontiguousarray(a), np.ascontiguousarray(b)
        if self.initial_state:
            rest_kernel(a_c, b_c, self.delay, m2, c1, c2, self.u, self.y0, delta0, self.x, self.y_hat, self.zone)
        else:
            simulate_kernel(a_c, b_c, self.delay, m2, c1, c2, self.u, self.y0, self.x, self.y_hat, self.zone)
        return True

    def __call__(self, p: np.ndarray) -> np.ndarray:
        _threads.check()  # inside a live run's wall budget the search stops here (nothing is checked outside one)
        if not self.simulate(p):
            return np.full(self.y_used.shape, self.failure)
        out: np.ndarray = self.y_hat - self.y
        if self.keep is not None:
            out = out[self.keep]
        if not np.all(np.isfinite(out)):
            return np.full(self.y_used.shape, self.failure)
        return out

    def model(self, p: np.ndarray) -> BacklashModel:
        a, b, m2, c1, c2, _ = self.split(p)
        return BacklashModel(a=tuple(a), b=tuple(b), delay=self.delay, m2=m2, c1=c1, c2=c2)


def output_error_jacobian(residual: np.ndarray, jac: np.ndarray, n_params: int) -> tuple[np.ndarray, np.ndarray]:
    """Covariance and standard errors ``s^2 (J^T J)^+`` of a least-squares fit.

    See :func:`servoid.ident.offline._oefit.covariance_from_jacobian` (kept here for
    callers of this module).
    """
    return covariance_from_jacobian(residual, jac, n_params)


def refine(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    initial: BacklashModel,
    *,
    y0: float | None = None,
    max_nfev: int | None = None,
    valid: Sequence[bool] | np.ndarray | None = None,
    initial_state: bool = False,
    delta0: float = 0.0,
    play: float | None = None,
) -> Refinement:
    """Fit all parameters of ``initial`` to ``(u, y)`` by simulation-error least squares.

    Parameters
    ----------
    u, y : array_like
        The record: input and measured output, same length, finite.
    initial : BacklashModel
        Start of the search and template for the orders and delay (kept fixed).
    y0 : float, optional
        Backlash output before the first sample; default ``y[0]`` (the first valid one).
    max_nfev : int, optional
        Cap on the number of simulations (default: scipy's, 100 per parameter).
    valid : array_like of bool, optional
        ``False`` marks samples whose measurement was lost (a live session's
        late, missed or timed-out samples) or that are held out (validation
        blocks): the model is simulated through them with their ``u``, but
        their ``y`` (which may be NaN) is not fitted.
    initial_state : bool
        Start the simulation from rest (:func:`~servoid.ident.models.kernels.rest_kernel`)
        and fit ``delta0``, where in the play the record starts; use it on
        records centred on their operating point
        (:mod:`servoid.ident.offline.operating_point`). False: from ``x = 0``.
    delta0 : float
        Start of ``delta0`` (with ``initial_state``).
    play : float, optional
        Hold ``c1 + c2`` at this value (``> 0``) and fit the rest: a point of
        the play's profile (:mod:`servoid.ident.offline.intervals`).

    Returns
    -------
    Refinement

    Notes
    -----
    The free-run error is piecewise smooth in the parameters (a change of a
    parameter moves the switching instants of the backlash only in jumps), so
    the trust-region search uses forward differences with a small relative
    step. Bounds keep ``m2``, ``c1`` and ``c2`` positive; stability of the
    linear block is kept by a penalty.
    """
    valid_arr: np.ndarray | None = None
    if valid is None:
        u_arr, y_arr, start_y = fit_record(u, y, initial.n_params, y0)
    else:
        u_arr, y_arr, start_y, valid_arr = _masked_record(u, y, valid, initial.n_params, y0)
    if play is not None:
        play = validation.positive("play", play)
    problem = _OutputError(u_arr, y_arr, initial, start_y, valid_arr, initial_state=initial_state, play=play)
    lay = initial.layout
    values0 = initial.values()
    y_std = float(np.std(problem.y_used))
    floor = _LOWER_BOUND_REL * max(y_std, 1e-12)
    if play is not None:
        values0[lay.c1] = float(np.clip(values0[lay.c1] * play / initial.dead_zone, 2 * floor, play - 2 * floor))
        values0[lay.c2] = play - values0[lay.c1]
    p0 = problem.pack(values0, validation.real("delta0", delta0))
    lower = np.full(p0.size, -np.inf)
    upper = np.full(p0.size, np.inf)
    lower[lay.m2 : lay.c2 + (0 if play is not None else 1)] = floor
    if play is not None:
        upper[lay.c1] = play - floor
    p0 = np.clip(p0, lower + floor, upper - floor)  # least_squares needs a strictly feasible start

    # the start's fit before the search: its residual is gone before the search's is made
    initial_nrmse = residual_nrmse(problem(p0), y_std)
    fit = fit_output_error(problem, p0, lower, upper, max_nfev=max_nfev)
    model = problem.model(fit.x)
    _, delta_hat = problem.full(fit.x)
    n_model = model.n_params
    stderr = np.full(n_model, np.nan)
    kept = [i for i in range(n_model) if play is None or i != lay.c2]
    stderr[kept] = fit.stderr[: len(kept)]
    return Refinement(
        model=model,
        initial=initial,
        stderr=tuple(float(s) for s in stderr),
        covariance=fit.covariance,
        nrmse=residual_nrmse(fit.residual, y_std),
        initial_nrmse=initial_nrmse,
        residual_std=float(np.std(fit.residual)),
        nfev=fit.nfev,
        success=fit.success,
        message=fit.message,
        delta0=delta_hat,
        initial_state=initial_state,
        residual=fit.residual,
        jacobian=fit.jacobian,
        sse=float(fit.residual @ fit.residual),
    )


def _masked_record(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    valid: Sequence[bool] | np.ndarray,
    n_params: int,
    y0: float | None,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """:func:`fit_record` for a record with lost samples: their ``y`` (maybe NaN) becomes 0, never fitted."""
    u_arr = validation.signal("u", u)
    valid_arr = np.asarray(valid, dtype=np.bool_)
    y_raw = np.asarray(y, dtype=np.float64)
    if valid_arr.shape != u_arr.shape or y_raw.shape != u_arr.shape:
        raise ConfigError(f"u, y and valid differ in shape: {u_arr.shape}, {y_raw.shape}, {valid_arr.shape}")
    y_arr = validation.signal("y (valid samples)", np.where(valid_arr, y_raw, 0.0))
    used = int(valid_arr.sum())
    if used <= n_params:
        raise ConfigError(f"{used} samples cannot determine {n_params} parameters")
    start_y = float(y_arr[int(np.argmax(valid_arr))]) if y0 is None else validation.real("y0", y0)
    return u_arr, y_arr, start_y, valid_arr


#: Rows of the ARX regression per chunk: its memory stays a few MB whatever the record's length.
ARX_CHUNK = 1 << 16


def _arx_least_squares(
    u: np.ndarray, y: np.ndarray, usable: np.ndarray, *, na: int, nb: int, delay: int, k0: int
) -> np.ndarray:
    """The least-squares ARX parameters ``[a, b, offset]``, the regression built and reduced chunk by chunk.

    Each chunk's rows ``[-y(k-1) .. -y(k-na), u(k-d) .. u(k-d-nb), 1 | y(k)]``
    are stacked under the triangle kept so far and reduced by a QR
    decomposition to a new triangle ``[R | Q^T y]`` (a streaming QR): the
    same least-squares problem as the whole regressor matrix, with the
    conditioning of ``lstsq`` on it (not the squared one of the normal
    equations), in memory independent of the record's length (the whole
    matrix cost ~100 bytes per sample at 10^6 and more). ``lstsq`` on the
    final triangle keeps its rank handling: ``R`` has the singular values of
    the whole matrix.
    """
    p = na + nb + 2
    tri = np.zeros((0, p + 1))
    rows = y.size - k0
    for lo in range(0, rows, ARX_CHUNK):
        hi = min(rows, lo + ARX_CHUNK)
        block = np.empty((hi - lo, p + 1))
        for i in range(1, na + 1):
            block[:, i - 1] = -y[k0 + lo - i : k0 + hi - i]
        for j in range(nb + 1):
            block[:, na + j] = u[k0 + lo - delay - j : k0 + hi - delay - j]
        block[:, p - 1] = 1.0
        block[:, p] = y[k0 + lo : k0 + hi]
        tri = np.asarray(np.linalg.qr(np.vstack((tri, block[usable[lo:hi]])), mode="r"))[: p + 1]
    theta: np.ndarray = np.linalg.lstsq(tri[:p, :p], tri[:p, p], rcond=None)[0]
    return theta


def arx_start(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    *,
    na: int,
    nb: int,
    delay: int,
    valid: Sequence[bool] | np.ndarray | None = None,
) -> BacklashModel:
    """A starting model that does not depend on the MRGIA: ARX for the linear block, a small backlash.

    The linear block comes from the least-squares (equation-error) fit of
    ``y(k) = -sum a_i y(k-i) + sum b_j u(k-d-j) + offset``, treating the
    backlash as a disturbance (the offset absorbs ``c1 != c2``); it is
    biased, but lands close enough for the output-error search where the
    MRGIA does not converge (see
    :func:`servoid.ident.online.mrgia.convergence_margin`). An unstable fit is
    pulled inside the unit circle. The backlash starts with ``m2 = 1`` and
    dead zones of 5 % of ``std(y)``.

    With ``valid`` (False: a lost sample, whose ``y`` may be NaN), only the
    equations whose ``y`` terms were all measured are used.

    Parameters
    ----------
    u, y : array_like
        The record: input and measured output, same length.
    na, nb, delay : int
        Orders and delay of the model to start.
    valid : array_like of bool, optional
        Which samples were measured.

    Returns
    -------
    BacklashModel

    Raises
    ------
    ConfigError
        For records too short or arrays of different length.
    """
    if valid is None:
        u_arr, y_arr = validation.signal("u", u), validation.signal("y", y)
        keep = np.ones(u_arr.size, dtype=np.bool_)
    else:
        u_arr, y_arr, _, keep = _masked_record(u, y, valid, na + nb + 2, None)
    if u_arr.size != y_arr.size:
        raise ConfigError(f"u and y differ in length: {u_arr.size} against {y_arr.size}")
    k0 = max(na, delay + nb)
    usable = keep[k0:].copy()
    for i in range(1, na + 1):
        usable &= keep[k0 - i : keep.size - i]
    if int(usable.sum()) <= na + nb + 2:
        raise ConfigError(f"{y_arr.size} samples are too few for an ARX start with na={na}, nb={nb}, delay={delay}")
    theta = _arx_least_squares(u_arr, y_arr, usable, na=na, nb=nb, delay=delay, k0=k0)
    a = theta[:na]
    b = theta[na : na + nb + 1]
    while np.max(np.abs(np.roots(np.r_[1.0, a]))) >= 0.995:
        a = a * 0.95 ** np.arange(1, na + 1)  # scales every pole by 0.95
    y_std = float(np.std(y_arr[keep]))
    if not np.any(b):
        b = np.r_[max(y_std / max(float(np.std(u_arr)), 1e-12), 1e-6), b[1:]]
    dead = max(0.05 * y_std, 1e-9)
    return BacklashModel(a=tuple(a.tolist()), b=tuple(b.tolist()), delay=delay, m2=1.0, c1=dead, c2=dead)
