"""Figures of a comparison: measured against each model's free run, the ``resid`` checks, Bode and step of the linear block."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from servoid.ident.diagnosis.compare import Comparison
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.plots._base import figure as _figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_compare", "plot_resid", "plot_linear_block"]


def _mark_left_out(ax: Axes, axis: np.ndarray, valid: np.ndarray | None) -> None:
    """Shade the runs of samples the fit leaves out."""
    if valid is None or valid.all():
        return
    edges = np.flatnonzero(np.diff(np.concatenate(([0], (~valid).astype(np.int8), [0]))))
    for i, (lo, hi) in enumerate(zip(edges[::2], edges[1::2])):
        ax.axvspan(axis[lo], axis[min(hi, axis.size - 1)], color="tab:red", alpha=0.15, lw=0,
                   label="left out" if i == 0 else None)  # fmt: skip


def plot_compare(
    comparison: Comparison,
    *,
    t: np.ndarray | None = None,
    output_unit: str = "",
    window: int = 400,
    title: str = "Measured and simulated output (free run)",
) -> Figure:
    """Measured output against each model's free run (fit % in the legend): whole record, its end, residuals.

    Samples left out of the fit (lost or late) are shaded red.

    Parameters
    ----------
    comparison : Comparison
        What :func:`servoid.ident.diagnosis.compare.compare` returned.
    t : ndarray, optional
        Sample times in seconds (default: sample numbers).
    output_unit : str
        Unit of ``y``, for the axis label.
    window : int
        Samples shown in the middle panel (the last ones), to see the fit up close.
    title : str
        Title of the top panel.
    """
    n = comparison.samples
    axis = np.arange(n) if t is None else np.asarray(t, dtype=float)
    unit = f" [{output_unit}]" if output_unit else ""
    lo = max(0, n - window)
    fig = _figure(figsize=(10, 8))
    whole, last, bottom = fig.subplots(3, 1)
    for ax, sl in ((whole, slice(0, n)), (last, slice(lo, n))):
        ax.plot(axis[sl], comparison.y[sl], color="k", lw=1.2, label="measured")
        for i, fit in enumerate(comparison.fits):
            ax.plot(
                axis[sl], fit.y_hat[sl], color=f"C{i + 1}", lw=0.9, label=f"{fit.name}: fit {fit.fit_percent:.2f} %"
            )
        ax.set_ylabel("y" + unit)
    for i, fit in enumerate(comparison.fits):
        bottom.plot(axis, comparison.y - fit.y_hat, color=f"C{i + 1}", lw=0.6, label=fit.name)
    for ax in (whole, last, bottom):
        _mark_left_out(ax, axis, comparison.valid)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    whole.set_title(f"{title}: {comparison.used} of {n} samples scored")
    last.set_title(f"the last {n - lo} samples")
    bottom.set_ylabel("y - y_hat" + unit)
    bottom.set_title("residual")
    bottom.set_xlabel("sample k" if t is None else "time [s]")
    fig.tight_layout()
    return fig


def plot_resid(comparison: Comparison) -> Figure:
    """``resid``: the residual's autocorrelation and its cross-correlation with ``u(k - lag)``, with the band.

    Parameters
    ----------
    comparison : Comparison
        What :func:`servoid.ident.diagnosis.compare.compare` returned.
    """
    fig = _figure(figsize=(9, 6))
    axes = fig.subplots(2, 1, sharex=True)
    count = len(comparison.fits)
    width = 0.6 / count
    for ax, attr, title in ((axes[0], "autocorrelation", "autocorrelation of the residual"),
                            (axes[1], "cross_correlation", "cross-correlation of the residual with u(k - lag)")):  # fmt: skip
        for i, fit in enumerate(comparison.fits):
            tests = fit.resid
            start = 1 if attr == "autocorrelation" else 0
            shift = (i - (count - 1) / 2) * width
            ax.vlines(tests.lags[start:] + shift, 0, getattr(tests, attr)[start:], lw=2, color=f"C{i + 1}",
                      label=fit.name)  # fmt: skip
        first = comparison.fits[0].resid
        ax.axhspan(-first.band, first.band, color="0.85", zorder=0, label=f"{100 * first.confidence:.0f} % band")
        ax.axhline(0, color="k", lw=0.6)
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    verdicts = "; ".join(f"{f.name}: {f.verdict()}" for f in comparison.fits)
    fig.suptitle(verdicts if len(verdicts) < 110 else verdicts[:107] + "...", fontsize=9)
    axes[1].set_xlabel("lag [samples]")
    fig.tight_layout()
    return fig


def _settling_samples(model: BacklashModel) -> int:
    """Long enough for the step response to settle: about 7 time constants of the slowest pole."""
    slowest = max(abs(p) for p in model.poles)
    tau = 1.0 / -np.log(slowest) if slowest > 0 else 1.0
    return int(min(20_000, max(20, 7 * tau + model.delay + model.nb + 1)))


def plot_linear_block(
    models: Mapping[str, BacklashModel],
    *,
    sample_period_s: float | None = None,
    input_unit: str = "",
    output_unit: str = "",
) -> Figure:
    """Bode (magnitude, phase) and unit-step response of each model's linear block, the play said beside.

    The backlash has no frequency response: these are of the linear block
    ``x = z^-d B / A u`` alone; the legend gives each model's play
    ``c1 + c2`` and the same play referred to the input (``(c1 + c2) / gain``,
    how far the input must reverse before the output moves again).

    Parameters
    ----------
    models : mapping of str to BacklashModel
        The models, by name.
    sample_period_s : float, optional
        Sample period: frequency in Hz and time in seconds (default: per sample).
    input_unit, output_unit : str
        Units of ``u`` and ``y`` (and ``x``), for labels.
    """
    from servoid.ident.models.linear_block import frequency_response, step_response

    dt = sample_period_s
    fig = _figure(figsize=(11, 7))
    grid = fig.add_gridspec(2, 2)
    mag = fig.add_subplot(grid[0, 0])
    phase = fig.add_subplot(grid[1, 0], sharex=mag)
    step = fig.add_subplot(grid[:, 1])
    length = max(_settling_samples(model) for model in models.values())  # one time axis for every model
    out_u = output_unit or "unit of y"
    in_u = input_unit or "unit of u"
    for i, (name, model) in enumerate(models.items()):
        colour = f"C{i + 1}"
        resp = frequency_response(model)
        f = resp.frequency / dt if dt else resp.frequency
        gain = model.dc_gain
        referred = f", {model.dead_zone / abs(gain):.4g} {in_u} at the input" if gain != 0 else ""
        label = f"{name}: play c1 + c2 = {model.dead_zone:.4g} {out_u}{referred}"
        mag.semilogx(f, resp.magnitude_db, color=colour, lw=1.2, label=label)
        phase.semilogx(f, resp.phase_deg, color=colour, lw=1.2)
        x = step_response(model, length)
        k = np.arange(x.size)
        step.step(k * dt if dt else k, x, where="post", color=colour, lw=1.2, label=f"{name}: gain {gain:.4g}")
        step.axhline(gain, color=colour, ls=":", lw=0.8)
        # From rest the backlash holds y until x has crossed the up line's dead zone c1.
        step.axhspan(0.0, model.c1 if gain >= 0 else -model.c1, color=colour, alpha=0.12, lw=0,
                     label=f"{name}: x within c1 = {model.c1:.4g}, y not moving yet")  # fmt: skip
    mag.set_ylabel(f"|G| [dB, {out_u} per {in_u}]")
    mag.set_title("linear block (the backlash has no frequency response)")
    mag.grid(alpha=0.3, which="both")
    mag.legend(fontsize=7, loc="lower left")
    phase.set_ylabel("phase [deg]")
    phase.set_xlabel("frequency [Hz]" if dt else "frequency [cycles/sample]")
    phase.grid(alpha=0.3, which="both")
    step.set_title("unit step of u: x, before the play")
    step.set_xlabel("time [s]" if dt else "sample k")
    step.set_ylabel(f"x [{out_u}]")
    step.grid(alpha=0.3)
    step.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return fig
