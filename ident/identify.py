"""Identify a backlash model from a record: MRGIA, then output-error refinement.

This is the pipeline behind ``servoid identify``: validate the record, run the
MRGIA over it (online estimate), refine the estimate offline, and report both
with the free-run fit of the best one.
"""

from __future__ import annotations

import html
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, DataError, ModelError
from servoid.ident.diagnosis.compare import compare
from servoid.ident.metrics import nrmse
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import free_run
from servoid.ident.offline.refine import Refinement, arx_start, refine
from servoid.ident.online.mrgia import MRGIAConfig, MRGIAResult, convergence_margin, run_mrgia
from servoid.ident.reprs import html_table

__all__ = ["Identification", "identify", "check_record", "POOR_FIT_NRMSE"]

#: A free-run NRMSE from here on says the model explains almost nothing of y (1 is y's mean):
#: even output noise as strong as the signal itself (SNR 1) leaves a good model near 0.7.
POOR_FIT_NRMSE = 0.9

Method = Literal["mrgia", "mrgia+oe"]


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`.

    Attributes
    ----------
    model : BacklashModel
        The best estimate: refined when refinement ran, else the MRGIA's.
    method : {"mrgia", "mrgia+oe"}
        How :attr:`model` was obtained.
    mrgia : MRGIAResult
        The online estimate and its history.
    mrgia_model : BacklashModel or None
        The MRGIA estimate as a model, None when it is not a valid model.
    refinement : Refinement or None
        The output-error refinement that won, when refinement ran.
    refined_from : {"mrgia", "arx"} or None
        Which start that refinement came from: the MRGIA estimate, or the
        MRGIA-independent ARX start (:func:`servoid.ident.offline.refine.arx_start`).
    start_nrmse : dict
        Free-run NRMSE reached from each start that was tried.
    samples : int
        Length of the record.
    fit_nrmse : float
        ``rms(y - y_hat) / std(y)`` of the free-run simulation of :attr:`model`.
    mrgia_nrmse : float or None
        The same for the MRGIA estimate.
    warnings : tuple of str
        Things the user must know (an unsettled run, recoveries, an invalid
        online estimate, a refinement that did not converge).
    """

    model: BacklashModel
    method: Method
    mrgia: MRGIAResult
    mrgia_model: BacklashModel | None
    refinement: Refinement | None
    refined_from: str | None
    start_nrmse: dict[str, float]
    samples: int
    fit_nrmse: float
    mrgia_nrmse: float | None
    warnings: tuple[str, ...]

    def __repr__(self) -> str:
        fit = f"fit {100 * (1 - self.fit_nrmse):.2f} % (NRMSE {self.fit_nrmse:.4g})"
        said = f", {len(self.warnings)} warning(s)" if self.warnings else ""
        return f"Identification({self.method}, {self.samples} samples, {fit}{said}; {self.model!r})"

    def _repr_html_(self) -> str:
        cols, rows = self.table()
        caption = f"{self.method} on {self.samples} samples: free-run fit {100 * (1 - self.fit_nrmse):.2f} %"
        notes = "".join(f"<li>{html.escape(w)}</li>" for w in self.warnings)
        return html_table(cols, rows, caption=caption) + (f"<ul>{notes}</ul>" if notes else "")

    def table(self, truth: BacklashModel | None = None) -> tuple[list[str], list[list[str]]]:
        """Columns and rows of the parameter table: the MRGIA's and the refined values, standard errors.

        Parameters
        ----------
        truth : BacklashModel, optional
            The true plant, when known (a simulation): adds its values and the relative errors.
        """
        cols = ["parameter"] + (["true"] if truth is not None else []) + ["MRGIA"]
        if self.refinement is not None:
            cols += ["refined", "std err"]
        if truth is not None:
            cols.append("rel. error")
        stderr = self.stderr or {}
        rows = []
        for i, name in enumerate(self.model.names):
            row = [name] + ([f"{truth.values()[i]:.6g}"] if truth is not None else [])
            row.append(f"{self.mrgia.values()[i]:.6g}")
            if self.refinement is not None:
                row += [f"{self.model.values()[i]:.6g}", f"{stderr.get(name, float('nan')):.2g}"]
            if truth is not None:
                ref = truth.values()[i]
                row.append(f"{abs(self.model.values()[i] - ref) / abs(ref):.2e}")
            rows.append(row)
        return cols, rows

    def to_control(self, dt: float | bool = True) -> Any:
        """The identified linear block as a python-control ``TransferFunction`` (needs ``servoid[control]``).

        Parameters
        ----------
        dt : float or True
            Sample period in seconds; ``True`` (default) when it is not known.
        """
        return self.model.to_control(dt)

    @property
    def stderr(self) -> dict[str, float] | None:
        """Standard errors of :attr:`model`'s parameters, when refinement ran."""
        return None if self.refinement is None else self.refinement.stderr_dict()

    def to_dict(self) -> dict[str, Any]:
        """For JSON: ``model``, ``method``, ``samples``, ``fit_nrmse``, ``stderr``, ``refined_from``,
        ``start_nrmse``, ``mrgia`` (:meth:`MRGIAResult.to_dict` with its own ``fit_nrmse``) and ``warnings``.

        ``stderr`` is null without refinement; one of its entries is null where
        the data do not determine that parameter. ``mrgia.model`` is null (with
        ``model_error``) when the online estimate is not a valid model.
        """
        return {
            "model": self.model.to_dict(), "method": self.method, "samples": self.samples,
            "fit_nrmse": self.fit_nrmse, "stderr": self.stderr, "refined_from": self.refined_from,
            "start_nrmse": dict(self.start_nrmse), "mrgia": {**self.mrgia.to_dict(), "fit_nrmse": self.mrgia_nrmse},
            "warnings": list(self.warnings),
        }  # fmt: skip


def check_record(
    u: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray, config: MRGIAConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Validate a record for identification; return it as float arrays.

    Parameters
    ----------
    u, y : array_like
        Input and measured output.
    config : MRGIAConfig
        The orders and delay, which set how many samples are needed at least.

    Raises
    ------
    DataError
        Non-finite values, different lengths, too few samples for the orders,
        a constant input (it excites nothing) or a constant output (the servo
        never moved).
    """
    try:
        u_arr = validation.signal("u", u)
        y_arr = validation.signal("y", y)
    except ConfigError as exc:
        raise DataError(str(exc)) from None
    if u_arr.size != y_arr.size:
        raise DataError(f"u and y differ in length: {u_arr.size} against {y_arr.size}")
    minimum = 10 * config.n_params + config.delay + config.nb
    if u_arr.size < minimum:
        raise DataError(
            f"{u_arr.size} samples are too few to identify na={config.na}, nb={config.nb}, "
            f"delay={config.delay} ({config.n_params} parameters): at least {minimum} are needed"
        )
    if np.ptp(u_arr) == 0.0:
        raise DataError(f"the input u is constant (={u_arr[0]!r}): it excites nothing")
    if np.ptp(y_arr) == 0.0:
        raise DataError(f"the output y is constant (={y_arr[0]!r}): the servo never moved")
    return u_arr, y_arr


def identify(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    config: MRGIAConfig,
    *,
    refine_model: bool = True,
    record_every: int = 1,
    progress: Callable[[int, int], None] | None = None,
    valid: Sequence[bool] | np.ndarray | None = None,
    online: MRGIAResult | None = None,
) -> Identification:
    """Identify a backlash model from a record.

    Parameters
    ----------
    u, y : array_like
        Input and measured output.
    config : MRGIAConfig
        Orders, delay and estimator settings.
    refine_model : bool
        Run the output-error refinement after the MRGIA.
    record_every : int
        Sampling of the MRGIA's parameter history.
    progress : callable, optional
        Called as ``progress(done, total)`` while the MRGIA runs.
    valid : array_like of bool, optional
        ``False`` marks samples whose measurement was lost or is not to be
        trusted (a live session's late, missed and timed-out samples): their
        ``y`` may be NaN; the MRGIA skips them (:meth:`MRGIA.skip`) and the
        refinement and the fit leave them out, simulating through them.
    online : MRGIAResult, optional
        The MRGIA's result over this record, already computed (a live
        session ran it sample by sample: :meth:`servoid.session.listeners.EstimatorFeed.mrgia_result`);
        it is used as it is, and only the offline stage runs here. Its
        configuration must have ``config``'s orders and delay.

    Returns
    -------
    Identification

    Raises
    ------
    DataError
        For a record that cannot be identified (see :func:`check_record`).
    EstimatorDiverged
        If the MRGIA diverged, with the sample index.
    """
    u_arr, y_arr, keep = _record(u, y, valid, config)
    first = 0 if keep is None else int(np.argmax(keep))
    y0 = float(y_arr[first])
    warnings: list[str] = []
    if keep is not None and not keep.all():
        warnings.append(f"{int(keep.size - keep.sum())} of {keep.size} samples were lost or late and left out")
    if online is None:
        online = run_mrgia(u_arr, y_arr, config, valid=keep, record_every=record_every, progress=progress)
    elif (online.config.na, online.config.nb, online.config.delay) != (config.na, config.nb, config.delay):
        c = online.config
        raise ConfigError(
            f"the online result is for na={c.na}, nb={c.nb}, delay={c.delay}; "
            f"config asks for na={config.na}, nb={config.nb}, delay={config.delay}"
        )
    if online.recoveries:
        at = ", ".join(str(r.sample) for r in online.recoveries[:5])
        warnings.append(
            f"the MRGIA got stuck in a wrong zone classification and recovered "
            f"{len(online.recoveries)} time(s) (after samples {at})"
        )
    if not online.settled:
        warnings.append(
            "the MRGIA did not settle: at the end, line coverage is "
            f"up {online.coverage[0]:.2f} / down {online.coverage[1]:.2f} "
            f"(below {config.stuck_below}): the input may not reach both backlash lines, "
            "or the online estimate has not converged"
        )

    mrgia_model: BacklashModel | None
    mrgia_nrmse: float | None
    try:
        mrgia_model = online.model
        mrgia_nrmse = _fit(y_arr, free_run(mrgia_model, u_arr, y0=y0), keep)
    except ModelError as exc:
        mrgia_model, mrgia_nrmse = None, None
        warnings.append(str(exc))

    # Refine from the MRGIA estimate and from a start that does not depend on
    # it: where the MRGIA's convergence condition fails (slow plants), its
    # estimate can sit in another basin of the output error. Keep the best fit.
    refinement: Refinement | None = None
    refined_from: str | None = None
    start_nrmse: dict[str, float] = {}
    if refine_model:
        starts: dict[str, BacklashModel] = {
            "mrgia": mrgia_model if mrgia_model is not None else _feasible_start(online.theta, config)
        }
        try:
            starts["arx"] = arx_start(u_arr, y_arr, na=config.na, nb=config.nb, delay=config.delay, valid=keep)
        except (ConfigError, ModelError):
            pass
        for name, start in starts.items():
            candidate = refine(u_arr, y_arr, start, y0=y0, valid=keep)
            start_nrmse[name] = candidate.nrmse
            if refinement is None or candidate.nrmse < refinement.nrmse:
                refinement, refined_from = candidate, name
        assert refinement is not None
        if not refinement.success:
            warnings.append(f"the refinement did not converge: {refinement.message}")
        if mrgia_nrmse is not None and refinement.nrmse > mrgia_nrmse:
            warnings.append("the refinement fits worse than the MRGIA estimate; keeping the MRGIA estimate")
            refinement, refined_from = None, None

    if refinement is not None:
        model, method, fit = refinement.model, "mrgia+oe", refinement.nrmse
    elif mrgia_model is not None and mrgia_nrmse is not None:
        model, method, fit = mrgia_model, "mrgia", mrgia_nrmse
    else:
        raise ModelError(
            "no valid model: the MRGIA estimate is invalid and refinement was not requested "
            "(drop --no-refine, or check the orders and the input)"
        )
    online_poor = mrgia_nrmse is None or (refinement is not None and mrgia_nrmse > 2.0 * fit + 0.02)
    if online_poor and refinement is not None:
        margin = convergence_margin(model.a)
        why = (
            f": its convergence condition |A(e^jw) - 1| < 1 fails for this linear block (margin {margin:.2f}); "
            "sample more slowly"
            if margin < 0.0
            else " (a whiter input, e.g. uniform noise, helps the online estimate)"
        )
        warnings.append(
            f"the MRGIA's online estimate did not converge here (fit NRMSE "
            f"{'n/a' if mrgia_nrmse is None else f'{mrgia_nrmse:.3g}'} against {fit:.3g} refined from the "
            f"{refined_from} start){why}; the refined model is the one to use"
        )
    if fit >= POOR_FIT_NRMSE:
        warnings.append(
            f"the model explains almost nothing of y: free-run NRMSE {fit:.3g} (1 is no better than y's mean); "
            "y may not depend on u here (check the columns, the delay and the orders): its parameters mean nothing"
        )
    coloured = compare({"the identified model": model}, u_arr, y_arr, valid=keep).fits[0].coloured_warning()
    if coloured is not None:
        warnings.append(coloured)
    return Identification(
        model=model,
        method=method,  # type: ignore[arg-type]
        mrgia=online,
        mrgia_model=mrgia_model,
        refinement=refinement,
        refined_from=refined_from,
        start_nrmse=start_nrmse,
        samples=int(u_arr.size),
        fit_nrmse=fit,
        mrgia_nrmse=mrgia_nrmse,
        warnings=tuple(warnings),
    )


def _record(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    valid: Sequence[bool] | np.ndarray | None,
    config: MRGIAConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The record as arrays, checked; lost samples' ``y`` set to 0 (never used) and the mask."""
    if valid is None:
        u_arr, y_arr = check_record(u, y, config)
        return u_arr, y_arr, None
    keep = np.asarray(valid, dtype=np.bool_)
    try:
        u_arr = validation.signal("u", u)
    except ConfigError as exc:
        raise DataError(str(exc)) from None
    y_raw = np.asarray(y, dtype=np.float64)
    if keep.shape != u_arr.shape or y_raw.shape != u_arr.shape:
        raise DataError(f"u, y and valid differ in shape: {u_arr.shape}, {y_raw.shape}, {keep.shape}")
    check_record(u_arr[keep], y_raw[keep], config)  # enough valid samples, finite, not constant
    return u_arr, np.where(keep, y_raw, 0.0), keep


def _fit(y: np.ndarray, y_hat: np.ndarray, keep: np.ndarray | None) -> float:
    return nrmse(y, y_hat) if keep is None else nrmse(y[keep], y_hat[keep])


def _feasible_start(theta: np.ndarray, config: MRGIAConfig) -> BacklashModel:
    """Nearest usable model to an invalid estimate, to start the refinement from.

    Dead zones and ``m2`` are raised to small positive values; an unstable
    linear block is pulled inside the unit circle by scaling its poles.
    """
    th = np.array(theta, dtype=np.float64)
    na, nb = config.na, config.nb
    lay = config.theta_layout
    th[lay.m2] = max(th[lay.m2], 0.05 - 1.0)
    th[lay.c1] = max(th[lay.c1], 1e-3)
    th[lay.c2] = max(th[lay.c2], 1e-3)
    if not any(th[lay.b]):
        th[lay.b.start] = 1.0
    for _ in range(200):
        try:
            return BacklashModel.from_theta(th, na=na, nb=nb, delay=config.delay)
        except ModelError:
            th[:na] *= 0.9 ** np.arange(1, na + 1)  # poles scale by 0.9
    raise ModelError(f"cannot build a starting model from the estimate {theta.tolist()}")
