"""Output-error least squares, shared by :func:`servoid.ident.offline.refine` and the extended-model fit.

Both minimise ``sum (y_hat(p) - y)^2`` of a free-run simulation over a
parameter vector with :func:`scipy.optimize.least_squares` and report
standard errors from the Jacobian at the optimum; only the simulation and
the parameter layout differ.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from servoid import validation
from servoid.errors import ConfigError

try:  # pragma: no cover - a dependency of servoid; without it fits are merely slower on a busy machine
    from threadpoolctl import threadpool_limits
except ImportError:  # pragma: no cover
    threadpool_limits = None

__all__ = [
    "OEFit",
    "fit_output_error",
    "covariance_from_jacobian",
    "failure_residual",
    "single_threaded_blas",
    "fit_record",
]


@dataclass(frozen=True)
class OEFit:
    """Raw result of :func:`fit_output_error`.

    Attributes
    ----------
    x : ndarray
        The parameters at the optimum.
    residual : ndarray
        ``y_hat - y`` there.
    covariance, stderr : ndarray
        ``s^2 (J^T J)^+`` and the square roots of its diagonal (NaN where the
        data do not determine a direction).
    jacobian : ndarray
        The residual's Jacobian at the optimum (the optimiser's last one).
    nfev : int
        Simulations used.
    success : bool
        Whether the optimiser reported convergence.
    message : str
        The optimiser's message.
    """

    x: np.ndarray
    residual: np.ndarray
    covariance: np.ndarray
    stderr: np.ndarray
    jacobian: np.ndarray
    nfev: int
    success: bool
    message: str


def fit_record(u: Any, y: Any, n_params: int, y0: float | None) -> tuple[np.ndarray, np.ndarray, float]:
    """Validate a record for an output-error fit: ``(u, y, y0)`` with ``y0`` defaulting to ``y[0]``.

    Raises
    ------
    ConfigError
        Non-finite values, different lengths, or too few samples for ``n_params``.
    """
    u_arr = validation.signal("u", u)
    y_arr = validation.signal("y", y)
    if u_arr.size != y_arr.size:
        raise ConfigError(f"u and y differ in length: {u_arr.size} against {y_arr.size}")
    if u_arr.size <= n_params:
        raise ConfigError(f"{u_arr.size} samples cannot determine {n_params} parameters")
    start_y = float(y_arr[0]) if y0 is None else validation.real("y0", y0)
    return u_arr, y_arr, start_y


def failure_residual(y: np.ndarray) -> np.ndarray:
    """A large constant residual for parameters where the simulation is invalid (unstable, non-finite).

    The trust region then steps back instead of failing on ``inf``.
    """
    return np.full(y.shape, 10.0 * (float(np.max(np.abs(y))) + float(np.std(y)) + 1.0))


def covariance_from_jacobian(residual: np.ndarray, jac: np.ndarray, n_params: int) -> tuple[np.ndarray, np.ndarray]:
    """Covariance and standard errors ``s^2 (J^T J)^+`` of a least-squares fit.

    ``s^2 = sum(residual^2) / (N - p)``. Directions the data do not determine
    (singular ``J^T J``) get NaN standard errors rather than a made-up number.
    """
    dof = max(residual.size - n_params, 1)
    s2 = float(residual @ residual) / dof
    jtj = jac.T @ jac
    cov = s2 * np.linalg.pinv(jtj)
    rank = np.linalg.matrix_rank(jtj)
    stderr = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if rank < n_params:
        stderr[:] = np.nan
    return cov, stderr


def single_threaded_blas() -> AbstractContextManager[Any]:
    """Run BLAS on one thread inside the block.

    The least-squares steps factor tall, thin Jacobians (thousands of rows, a
    few columns): threading them buys nothing, and on a loaded machine it
    costs 10-50x (measured on 2 cores shared with other work).
    """
    if threadpool_limits is None:  # pragma: no cover
        return contextlib.nullcontext()
    limits: AbstractContextManager[Any] = threadpool_limits(limits=1, user_api="blas")
    return limits


def fit_output_error(
    residual: Callable[[np.ndarray], np.ndarray],
    p0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    max_nfev: int | None = None,
) -> OEFit:
    """Minimise ``|residual(p)|^2`` from ``p0`` within ``[lower, upper]``.

    Notes
    -----
    The free-run error is piecewise smooth in the parameters (a change of a
    parameter moves the switching instants of the backlash and of the other
    nonlinear blocks only in jumps), so the trust-region search uses forward
    differences with a small relative step. ``p0`` is moved strictly inside
    the bounds, as ``least_squares`` requires.
    """
    start = np.clip(p0, np.nextafter(lower, np.inf), np.nextafter(upper, -np.inf))
    with single_threaded_blas():
        sol = least_squares(
            residual, start, bounds=(lower, upper),
            method="trf", x_scale="jac", diff_step=1e-7, max_nfev=max_nfev,
        )  # fmt: skip
        res = residual(sol.x)
        cov, stderr = covariance_from_jacobian(res, sol.jac, start.size)
    return OEFit(
        x=np.asarray(sol.x), residual=res, covariance=cov, stderr=stderr, jacobian=np.asarray(sol.jac),
        nfev=int(sol.nfev), success=bool(sol.success), message=str(sol.message),
    )  # fmt: skip
