"""How well models explain a record they may not have seen: free-run fit % as MATLAB's ``compare`` reports it, and ``resid``'s checks.

:func:`compare` simulates each model on the record's input (free run: no
measured output is fed back) and reports the fit
``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` %, which is MATLAB's
``compare`` (NRMSE fit) and ``100 (1 - NRMSE)`` with servoid's NRMSE
(:func:`servoid.ident.metrics.nrmse`): 100 % is a perfect fit, 0 % no
better than the output's mean, negative worse than it. Each residual then
gets the ``resid`` checks of :func:`servoid.ident.diagnosis.residuals.residual_tests`
(autocorrelation, and cross-correlation with past inputs, with a 99 % band).

The simulation starts as :func:`servoid.ident.identify.identify`'s does:
the linear block from rest, the backlash holding the first measured output.
Samples marked not valid (lost or late in a live recording) are simulated
through and left out of the fit and the correlations.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, DataError
from servoid.ident.diagnosis.residuals import ResidualTests, residual_tests
from servoid.ident.metrics import nrmse
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import free_run
from servoid.ident.offline._oefit import on_one_blas_thread
from servoid.ident.reprs import html_table

__all__ = ["ModelFit", "Comparison", "compare", "fit_percent", "output_resolution", "NUMERICAL_NRMSE"]

#: A fit this close is exact up to rounding: its residual is arithmetic, not a missed dynamic, and is not tested.
NUMERICAL_NRMSE = 1e-6


def fit_percent(nrmse_value: float) -> float:
    """MATLAB's NRMSE fit ``100 (1 - NRMSE)`` in %, from servoid's NRMSE ``rms(y - y_hat) / std(y)``.

    Parameters
    ----------
    nrmse_value : float
        The NRMSE, ``>= 0``.
    """
    return 100.0 * (1.0 - validation.non_negative("nrmse", nrmse_value))


def output_resolution(y: np.ndarray) -> float | None:
    """The step of a quantised output: the smallest gap between its values, when every gap is a whole number of it.

    Parameters
    ----------
    y : ndarray
        The measured output (finite).

    Returns
    -------
    float or None
        The step (an encoder's count in the output's unit), or None for an
        output that is not on a grid (noise, or too few distinct values).
    """
    gaps = np.diff(np.unique(y))
    if gaps.size < 2:
        return None
    step = float(gaps.min())
    ratio = gaps / step
    return step if float(np.max(np.abs(ratio - np.round(ratio)))) < 1e-6 else None


@dataclass(frozen=True, repr=False, eq=False)
class ModelFit:
    """One model's free run on a record.

    Attributes
    ----------
    name : str
        What the model is called (its file, or the key it was given under).
    model : BacklashModel
        The model.
    y_hat : ndarray
        Its free-run output on the record's input, unit of ``y``.
    nrmse : float
        ``rms(y - y_hat) / std(y)`` over the valid samples.
    residual_rms : float
        ``rms(y - y_hat)`` over the valid samples, unit of ``y``.
    resid : ResidualTests
        Autocorrelation of the residual and its cross-correlation with the input.
    resolution : float or None
        The step of a quantised output (an encoder's count), when ``y`` is one
        (:func:`output_resolution`).
    """

    name: str
    model: BacklashModel
    y_hat: np.ndarray
    nrmse: float
    residual_rms: float
    resid: ResidualTests
    resolution: float | None = None

    @property
    def below_floor(self) -> bool:
        """The residual is rounding (NRMSE below :data:`NUMERICAL_NRMSE`) or within one step of a quantised output.

        Its correlations then show the arithmetic or the encoder (a held
        position's rounding error stays put while the output stands still),
        not a dynamic the model misses.
        """
        return self.nrmse < NUMERICAL_NRMSE or (self.resolution is not None and self.residual_rms < self.resolution)

    @property
    def fit_percent(self) -> float:
        """MATLAB's NRMSE fit, ``100 (1 - nrmse)`` %."""
        return fit_percent(self.nrmse)

    @property
    def coloured(self) -> bool:
        """The residual fails the whiteness test (:attr:`ResidualTests.white`, Ljung-Box): the model misses dynamics.

        Never for a residual below the floor the output can show (:attr:`below_floor`).
        Identification's verdict reads this too (its rule on the black box's residual).
        """
        return not self.resid.white and not self.below_floor

    def coloured_warning(self) -> str | None:
        """One line saying the residual is coloured, or None when it is not."""
        if not self.coloured:
            return None
        return (
            f"the residual of {self.name} is coloured: it {self.resid.whiteness_text()}, so the model "
            "misses some dynamics (try other orders or delay, or servoid diagnose)"
        )

    def verdict(self) -> str:
        """One line on the residual: white, or where it holds structure."""
        if self.nrmse < NUMERICAL_NRMSE:
            return "exact up to rounding"
        if self.below_floor:
            return f"within the output's resolution ({self.resolution:.3g})"
        problems = []
        if self.coloured:
            problems.append(f"coloured (Ljung-Box Q {self.resid.ljung_box_q:.3g} > {self.resid.ljung_box_limit:.3g}; "
                            f"outside the band at {self.resid.autocorrelation_outside} lags)")  # fmt: skip
        if not self.resid.independent_of_input:
            problems.append(f"correlated with the input ({self.resid.cross_correlation_outside} lags)")
        return "; ".join(problems) if problems else "white and independent of the input"

    def to_dict(self) -> dict[str, Any]:
        """``{"name", "model", "fit_percent", "nrmse", "residual_rms", "resolution", "coloured", "resid"}``."""
        return {"name": self.name, "model": self.model.to_dict(), "fit_percent": self.fit_percent,
                "nrmse": self.nrmse, "residual_rms": self.residual_rms, "resolution": self.resolution,
                "coloured": self.coloured,
                "resid": self.resid.to_dict()}  # fmt: skip

    def __repr__(self) -> str:
        return f"ModelFit({self.name!r}: fit {self.fit_percent:.2f} %, residual {self.verdict()})"


@dataclass(frozen=True, repr=False, eq=False)
class Comparison:
    """Models simulated on one record: :func:`compare`'s result.

    Attributes
    ----------
    fits : tuple of ModelFit
        One per model, in the order given.
    u, y : ndarray
        The record (``y`` may be NaN where a sample is not valid).
    valid : ndarray of bool or None
        Samples the fit and correlations use; None: all.
    """

    fits: tuple[ModelFit, ...]
    u: np.ndarray
    y: np.ndarray
    valid: np.ndarray | None

    @property
    def samples(self) -> int:
        """Length of the record."""
        return int(self.u.size)

    @property
    def used(self) -> int:
        """Samples the fit uses."""
        return self.samples if self.valid is None else int(np.count_nonzero(self.valid))

    @property
    def best(self) -> ModelFit:
        """The model with the highest fit."""
        return max(self.fits, key=lambda f: f.fit_percent)

    def __getitem__(self, name: str) -> ModelFit:
        for fit in self.fits:
            if fit.name == name:
                return fit
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """``{"samples", "used_samples", "models": [ModelFit.to_dict(), ...]}``."""
        return {"samples": self.samples, "used_samples": self.used, "models": [f.to_dict() for f in self.fits]}

    def rows(self) -> tuple[list[str], list[list[str]]]:
        """Columns and rows of the table the command line and a notebook show."""
        cols = ["model", "fit %", "NRMSE", "residual RMS", "residual"]
        rows = [[f.name, f"{f.fit_percent:.2f}", f"{f.nrmse:.4g}", f"{f.residual_rms:.4g}", f.verdict()]
                for f in self.fits]  # fmt: skip
        return cols, rows

    def __repr__(self) -> str:
        fits = ", ".join(f"{f.name!r} {f.fit_percent:.2f} %" for f in self.fits)
        left = "" if self.valid is None else f" ({self.samples - self.used} left out)"
        return f"Comparison({self.samples} samples{left}; fit: {fits})"

    def _repr_html_(self) -> str:
        cols, rows = self.rows()
        left = "" if self.valid is None else f", {self.samples - self.used} left out"
        return html_table(cols, rows, caption=f"free-run fit on {self.samples} samples{left}")


@on_one_blas_thread
def compare(
    models: Mapping[str, BacklashModel] | BacklashModel,
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    *,
    valid: Sequence[bool] | np.ndarray | None = None,
    max_lag: int = 25,
    confidence: float = 0.99,
    starts: Mapping[str, tuple[float, tuple[float, float]]] | None = None,
) -> Comparison:
    """Simulate each model on the record's input and score it against the measured output.

    Parameters
    ----------
    models : BacklashModel or mapping of str to BacklashModel
        One model (named ``"model"``) or several by name.
    u, y : array_like
        The record: input and measured output.
    valid : array_like of bool, optional
        ``False`` marks samples to leave out of the fit and the correlations
        (their ``y`` may be NaN); the simulation runs through them.
    max_lag : int
        Largest lag of the correlations, in samples (lowered to a quarter of
        the valid samples on a short record).
    confidence : float
        Level of the correlations' band, in (0, 1).
    starts : mapping of str to (float, (float, float)), optional
        Per model name, where its record starts and the coordinates it was
        fitted in: ``(delta0, (u0, y0))`` as a model file keeps them (the
        initial state inside the play, the operating point), so that a
        model's fit on its own record is the fit ``identify`` reported. A
        model not named starts from rest with the backlash holding the first
        measured output, in the record's coordinates.

    Returns
    -------
    Comparison

    Raises
    ------
    DataError
        A record that cannot be scored: lengths differ, a value is not
        finite, too few valid samples, or a constant output.
    ConfigError
        No model, or a bad ``max_lag`` or ``confidence``.
    """
    named = {"model": models} if isinstance(models, BacklashModel) else dict(models)
    if not named:
        raise ConfigError("compare needs at least one model")
    for name, model in named.items():
        if not isinstance(model, BacklashModel):
            raise ConfigError(f"models[{name!r}] must be a BacklashModel, got {type(model).__name__}")
    try:
        u_arr = validation.signal("u", u)
        y_arr = np.asarray(y, dtype=np.float64)
        keep = None if valid is None else np.asarray(valid, dtype=np.bool_)
        if y_arr.shape != u_arr.shape or (keep is not None and keep.shape != u_arr.shape):
            shapes = f"{u_arr.shape}, {y_arr.shape}" + ("" if keep is None else f", {keep.shape}")
            raise DataError(f"u, y{'' if keep is None else ' and valid'} differ in shape: {shapes}")
        y_used = validation.signal("y", y_arr if keep is None else y_arr[keep], min_length=3)
    except (ConfigError, TypeError, ValueError) as exc:  # a DataError above keeps its message
        raise DataError(str(exc)) from None
    if np.ptp(y_used) == 0.0:
        raise DataError(f"the output y is constant (={y_used[0]!r}): a fit against it is undefined")
    max_lag = validation.integer("max_lag", max_lag, minimum=1)
    lag = max(1, min(max_lag, (y_used.size - 1) // 4))
    y0 = float(y_used[0])
    resolution = output_resolution(y_used)
    fits = []
    for name, model in named.items():
        if starts is not None and name in starts:
            delta0, (u_op, y_op) = starts[name]
            y_hat = free_run(model, u_arr - u_op, y0=y0 - y_op, delta0=delta0) + y_op
        else:
            y_hat = free_run(model, u_arr, y0=y0)
        residual = y_arr - y_hat
        part = residual if keep is None else residual[keep]
        fits.append(ModelFit(
            name=str(name), model=model, y_hat=y_hat,
            nrmse=nrmse(y_used, y_hat if keep is None else y_hat[keep]),
            residual_rms=float(np.sqrt(np.mean(part**2))),
            resid=residual_tests(residual, u_arr, max_lag=lag, confidence=confidence, valid=keep),
            resolution=resolution,
        ))  # fmt: skip
    return Comparison(fits=tuple(fits), u=u_arr, y=y_arr, valid=keep)
