"""Output-error least squares, shared by :func:`servoid.ident.offline.refine` and the extended-model fit.

Both minimise ``sum (y_hat(p) - y)^2`` of a free-run simulation over a
parameter vector with :func:`scipy.optimize.least_squares` and report
standard errors from the Jacobian at the optimum; only the simulation and
the parameter layout differ.
"""

from __future__ import annotations

import contextlib
import functools
import math
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any, ParamSpec, TypeVar

import numpy as np
from scipy.optimize import least_squares

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.models.kernels import normal_equations_kernel, schur_stable
from servoid.ident.offline import _threads

try:  # pragma: no cover - a dependency of servoid; without it fits are merely slower on a busy machine
    from threadpoolctl import ThreadpoolController
except ImportError:  # pragma: no cover
    ThreadpoolController = None

__all__ = [
    "OEFit",
    "fit_output_error",
    "covariance_from_jacobian",
    "failure_residual",
    "failure_level",
    "single_threaded_blas",
    "on_one_blas_thread",
    "fit_record",
]

P = ParamSpec("P")
R = TypeVar("R")


#: From this many residuals on, a pseudo-Wiener model's output error is minimised on normal equations
#: summed as the simulations run (:func:`_fit_streaming`): memory no longer grows with the record.
STREAM_FROM_ROWS = 50_000

#: From this many residuals on, the trust-region steps are solved by LSMR instead of an SVD of the
#: Jacobian (memory, see :func:`fit_output_error`; benchmarks/speed.py's identify() table).
LSMR_FROM_ROWS = 200_000


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
    return np.full(y.shape, failure_level(y))


def failure_level(y: np.ndarray) -> float:
    """The value of :func:`failure_residual`, for a caller that builds the array only when it is needed."""
    return 10.0 * (float(np.max(np.abs(y))) + float(np.std(y)) + 1.0)


def covariance_from_jacobian(residual: np.ndarray, jac: np.ndarray, n_params: int) -> tuple[np.ndarray, np.ndarray]:
    """Covariance and standard errors ``s^2 (J^T J)^+`` of a least-squares fit.

    ``s^2 = sum(residual^2) / (N - p)``. Directions the data do not determine
    (singular ``J^T J``) get NaN standard errors rather than a made-up number.
    """
    return covariance_from_normal(float(residual @ residual), jac.T @ jac, residual.size)


def covariance_from_normal(sum_sq: float, jtj: np.ndarray, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`covariance_from_jacobian` from the sums alone: ``sum r^2``, ``J^T J`` and the number of residuals.

    Parameters
    ----------
    sum_sq : float
        Sum of the squared residuals.
    jtj : ndarray, shape (p, p)
        ``J^T J``.
    rows : int
        Number of residuals.
    """
    n_params = jtj.shape[0]
    dof = max(rows - n_params, 1)
    s2 = sum_sq / dof
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
    costs 10-50x (measured on 2 cores shared with other work). The same holds
    for the residual analysis' dot products: on 2 busy cores, the 52 lagged
    products of 20 000 samples took 1.3 s threaded (each waits for a BLAS
    thread to be scheduled) and 4 ms on one thread.
    """
    if ThreadpoolController is None:  # pragma: no cover
        return contextlib.nullcontext()
    limits: AbstractContextManager[Any] = _blas_controller().limit(limits=1, user_api="blas")
    return limits


def on_one_blas_thread(func: Callable[P, R]) -> Callable[P, R]:
    """``func`` run inside :func:`single_threaded_blas` (a whole pipeline: its fits, intervals and residual tests)."""

    @functools.wraps(func)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        with single_threaded_blas():
            return func(*args, **kwargs)

    return run


@functools.cache
def _blas_controller() -> Any:
    """The BLAS libraries loaded, found once (``threadpool_limits`` looks for them on every call: ~1-13 ms)."""
    return ThreadpoolController()


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
    if _streamable(residual) and _rows(residual) >= STREAM_FROM_ROWS:
        with single_threaded_blas():
            return _fit_streaming(residual, start, lower, upper, max_nfev)
    with single_threaded_blas():
        rows = residual(start).size
        # The exact trust-region solver copies J into an augmented matrix and factors it by an SVD; LSMR
        # works on J in place: at 10^6 samples a refinement's peak falls from 457 to 384 bytes per sample
        # (the rest is scipy's own copies of J). Short records keep the exact steps and their numbers.
        solver = "lsmr" if rows >= LSMR_FROM_ROWS else "exact"
        budget = 100 * start.size if max_nfev is None else max_nfev  # scipy's default for trf
        sol = _search(residual, start, lower, upper, budget, solver)
        nfev = int(sol.nfev)
        # Restart a search that stopped on a small step or gain (ftol, xtol) from where it stopped, with a
        # fresh trust region: at a jump of the free-run error (a switching instant moved) the forward
        # differences mispredict, the region shrinks until a step gains under ftol, and the search stops
        # far from the minimum (the paper's plant, held PRBS, from the ARX start: max relative error 0.61,
        # 180 simulations; one restart: exact in 6 more). At a minimum a restart costs a few simulations.
        for _ in range(MAX_RESTARTS):
            if nfev >= budget or sol.status not in (2, 3, 4) or sol.cost == 0.0:  # ended on small steps only
                break
            again = _search(residual, sol.x, lower, upper, budget - nfev, solver)
            nfev += int(again.nfev)
            gained = again.cost < (1.0 - RESTART_GAIN) * sol.cost
            if again.cost < sol.cost:
                sol = again
            if not gained:
                break
        res = residual(sol.x)
        cov, stderr = covariance_from_jacobian(res, sol.jac, start.size)
    return OEFit(
        x=np.asarray(sol.x), residual=res, covariance=cov, stderr=stderr, jacobian=np.asarray(sol.jac),
        nfev=nfev, success=bool(sol.success), message=str(sol.message),
    )  # fmt: skip


#: Most restarts of a search that stopped on a small step or gain (:func:`fit_output_error`).
MAX_RESTARTS = 3

#: A restart that lowers the cost by more than this share is restarted in turn (up to :data:`MAX_RESTARTS`).
RESTART_GAIN = 1e-3


def _search(
    residual: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    max_nfev: int,
    solver: str,
) -> Any:
    """One trust-region search of :func:`fit_output_error` (``start`` kept strictly inside the bounds)."""
    x0 = np.clip(start, np.nextafter(lower, np.inf), np.nextafter(upper, -np.inf))
    return least_squares(residual, x0, bounds=(lower, upper), method="trf", x_scale="jac", diff_step=1e-7,
                         max_nfev=max(int(max_nfev), 1), tr_solver=solver)  # fmt: skip


# ---- long records: normal equations summed as the simulations run ------------------------------------
def _streamable(residual: object) -> bool:
    """Whether ``residual`` is a pseudo-Wiener output-error problem (the refinement's), which can stream."""
    return all(hasattr(residual, name) for name in ("u", "y", "keep", "y0", "na", "nb", "delay", "split"))


def _rows(problem: Any) -> int:
    return int(problem.u.size if problem.keep is None else np.count_nonzero(problem.keep))


class _Streamed:
    """Cost, ``J^T J`` and ``J^T r`` of a pseudo-Wiener problem at ``p``, from one pass of ``1 + p`` simulations."""

    def __init__(self, problem: Any, n: int) -> None:
        self.problem = problem
        self.keep = np.empty(0, dtype=np.bool_) if problem.keep is None else np.asarray(problem.keep, dtype=np.bool_)
        self.jtj = np.zeros((n, n))
        self.jtr = np.zeros(n)
        self._none = np.zeros((0, 0))
        self.nfev = 0

    def _models(self, ps: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        parts = [self.problem.split(q) for q in ps]
        na, nb = self.problem.na, self.problem.nb
        a = np.array([np.asarray(part[0], dtype=np.float64) for part in parts]).reshape(len(ps), na)
        b = np.array([np.asarray(part[1], dtype=np.float64) for part in parts]).reshape(len(ps), nb + 1)
        m2, c1, c2 = (np.array([part[i] for part in parts], dtype=np.float64) for i in (2, 3, 4))
        return a, b, m2, c1, c2

    def cost(self, p: np.ndarray) -> float:
        """``sum r^2`` at ``p`` (inf where the linear block is unstable or the simulation is not finite)."""
        _threads.check()  # a live run's wall budget, as the residual's evaluation checks it (refine's _OutputError)
        a = np.ascontiguousarray(self.problem.split(p)[0], dtype=np.float64)
        if not schur_stable(a):
            return math.inf
        self.nfev += 1
        return float(normal_equations_kernel(*self._models([p]), np.empty(0), self.problem.delay, self.problem.u,
                                             self.problem.y, self.keep, self.problem.y0, self._none, np.empty(0)))  # fmt: skip

    def normal(self, p: np.ndarray) -> float:
        """``sum r^2`` at ``p``, and :attr:`jtj`, :attr:`jtr` by forward differences (scipy's steps for ``diff_step=1e-7``)."""
        _threads.check()
        h = 1e-7 * np.where(p >= 0.0, 1.0, -1.0) * np.maximum(1.0, np.abs(p))
        h = (p + h) - p
        ps = [p]
        for j in range(p.size):
            q = p.copy()
            q[j] += h[j]
            ps.append(q)
        self.nfev += p.size + 1
        return float(normal_equations_kernel(*self._models(ps), h, self.problem.delay, self.problem.u, self.problem.y,
                                             self.keep, self.problem.y0, self.jtj, self.jtr))  # fmt: skip


def _fit_streaming(
    problem: Any, start: np.ndarray, lower: np.ndarray, upper: np.ndarray, max_nfev: int | None
) -> OEFit:
    """Levenberg-Marquardt on normal equations summed as the simulations run: no Jacobian, no residual vector.

    The refinement of a long record held the Jacobian (N x p) several times
    over in scipy's trust region (~400 bytes per sample at 10^6); here each
    iteration is one pass of ``1 + p`` simulations in step
    (:func:`~servoid.ident.models.kernels.normal_equations_kernel`), and a
    trial step one more. Steps solve ``(J^T J + lambda diag(J^T J)) d = -J^T r``
    (Marquardt's scaling), clipped into the bounds; a step that lowers the
    cost is taken and ``lambda`` shrinks tenfold, else it grows tenfold. It
    stops where scipy's ``least_squares`` does by default: a relative cost
    reduction below 1e-8, a step below 1e-8 relative, or 100 simulation passes
    per parameter. The residual vector is made once, at the end.
    """
    n = start.size
    lo, hi = np.nextafter(lower, np.inf), np.nextafter(upper, -np.inf)
    budget = 100 * n if max_nfev is None else max_nfev
    s = _Streamed(problem, n)
    p = start.copy()
    cost = s.normal(p) if math.isfinite(s.cost(p)) else math.inf
    success, message = False, "the number of simulations reached max_nfev"
    if not math.isfinite(cost):
        success, message = False, "the starting model cannot be simulated"
    lam = 1e-3
    while math.isfinite(cost) and s.nfev < budget:
        if cost == 0.0 or not np.any(s.jtr):
            success, message = True, "the cost is zero or its gradient vanishes"
            break
        scale = np.diag(s.jtj).copy()
        scale[scale <= 0.0] = max(float(np.max(scale)), 1.0) * 1e-12
        try:
            delta = np.linalg.solve(s.jtj + lam * np.diag(scale), -s.jtr)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        trial = np.clip(p + delta, lo, hi)
        step = trial - p
        if np.linalg.norm(step) <= 1e-8 * (1e-8 + np.linalg.norm(p)):
            success, message = True, "the step is below xtol"
            break
        trial_cost = s.cost(trial)
        if trial_cost < cost:
            reduction = (cost - trial_cost) / cost
            p = trial
            cost = s.normal(p)
            lam = max(lam / 10.0, 1e-15)
            if reduction < 1e-8:
                success, message = True, "the cost reduction is below ftol"
                break
        else:
            lam *= 10.0
            if lam > 1e15:
                success, message = True, "no step lowers the cost any further"
                break
    res = problem(p)
    cov, stderr = covariance_from_normal(cost, s.jtj, _rows(problem)) if math.isfinite(cost) else (
        np.full((n, n), np.nan), np.full(n, np.nan))  # fmt: skip
    # no Jacobian is held (that is the point): an empty one says so, and the play's interval comes from the
    # covariance and the residual (:func:`servoid.ident.offline.intervals.streamed_stderr`)
    return OEFit(x=p, residual=res, covariance=cov, stderr=stderr, jacobian=np.zeros((0, n)), nfev=s.nfev,
                 success=success, message=message)  # fmt: skip
