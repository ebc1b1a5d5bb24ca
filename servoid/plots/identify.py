"""Figures of an identification: convergence, fit, backlash loop."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.online.mrgia import MRGIAResult
from servoid.plots._base import figure as _figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_convergence", "plot_fit", "plot_backlash"]


def plot_convergence(
    online: MRGIAResult,
    *,
    truth: BacklashModel | None = None,
    refined: BacklashModel | None = None,
    title: str = "MRGIA parameter estimates",
) -> Figure:
    """Each parameter estimate against samples, like the paper's Figs 3 and 4.

    True values are dashed where known, the refined values dotted, and
    recoveries from a stuck zone classification marked by grey lines. With a
    known truth, a last panel shows the maximum relative error on a log scale.
    """
    names = online.names
    values = online.values_history()
    k = online.history_samples
    panels = len(names) + (1 if truth is not None else 0)
    cols = 3
    rows = int(np.ceil(panels / cols))
    fig = _figure(figsize=(4.0 * cols, 2.6 * rows))
    axes = fig.subplots(rows, cols, sharex=True, squeeze=False)
    flat = axes.ravel()
    true_vals = truth.values() if truth is not None else None
    ref_vals = refined.values() if refined is not None else None
    for i, name in enumerate(names):
        ax = flat[i]
        ax.plot(k, values[:, i], lw=1.2, label="MRGIA")
        if true_vals is not None:
            ax.axhline(true_vals[i], color="k", ls="--", lw=1, label="true")
        if ref_vals is not None:
            ax.axhline(ref_vals[i], color="tab:red", ls=":", lw=1.5, label="refined")
        for event in online.recoveries:
            ax.axvline(event.sample, color="0.6", lw=0.8)
        ax.set_title(name)
        ax.grid(alpha=0.3)
        finite = values[np.isfinite(values[:, i]), i]
        if finite.size:
            tail = finite[finite.size // 10 :]
            centre = true_vals[i] if true_vals is not None else float(np.median(tail))
            spread = max(float(np.max(np.abs(tail - centre))), 0.5 * abs(centre), 0.1) * 1.5
            ax.set_ylim(centre - spread, centre + spread)
    if truth is not None and true_vals is not None:
        ax = flat[len(names)]
        scale = np.where(true_vals != 0, np.abs(true_vals), 1.0)
        err = np.max(np.abs(values - true_vals) / scale, axis=1)
        ax.semilogy(k, np.maximum(err, 1e-17), color="tab:purple", lw=1.2)
        ax.set_title("max relative error")
        ax.grid(alpha=0.3, which="both")
    for ax in flat[panels:]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("sample k")
    flat[0].legend(fontsize=8, loc="best")
    if online.recoveries:
        title += f"  ({len(online.recoveries)} recovery(ies), grey lines)"
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_fit(
    y: Sequence[float] | np.ndarray,
    simulated: Mapping[str, np.ndarray],
    *,
    u: Sequence[float] | np.ndarray | None = None,
    t: Sequence[float] | np.ndarray | None = None,
    window: int = 400,
    output_unit: str = "",
    title: str = "Measured and simulated output (free run)",
) -> Figure:
    """Measured output against free-run simulations, with residuals.

    Top: the last ``window`` samples, measured and each simulated output.
    Middle: the residual ``y - y_hat`` of each model over the whole record.
    Bottom (if ``u`` is given): the input over the same window as the top.
    """
    y_arr = np.asarray(y, dtype=float)
    n = y_arr.size
    axis = np.arange(n) if t is None else np.asarray(t, dtype=float)
    xlabel = "sample k" if t is None else "time [s]"
    unit = f" [{output_unit}]" if output_unit else ""
    lo = max(0, n - window)
    panels = 3 if u is not None else 2
    fig = _figure(figsize=(10, 2.6 * panels))
    axes = fig.subplots(panels, 1, squeeze=False)
    ax = axes[0, 0]
    ax.plot(axis[lo:], y_arr[lo:], color="k", lw=1.4, label="measured")
    for label, y_hat in simulated.items():
        ax.plot(axis[lo:], np.asarray(y_hat)[lo:], lw=1.0, label=label)
    ax.set_ylabel("y" + unit)
    ax.set_title(f"{title}: last {n - lo} samples")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[1, 0]
    for label, y_hat in simulated.items():
        ax.plot(axis, y_arr - np.asarray(y_hat), lw=0.6, label=label)
    ax.set_ylabel("y - y_hat" + unit)
    ax.set_title("residual, whole record")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_xlabel(xlabel)
    if u is not None:
        ax = axes[2, 0]
        ax.step(axis[lo:], np.asarray(u, dtype=float)[lo:], where="post", color="tab:green", lw=1.0)
        ax.set_ylabel("u")
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot_backlash(
    model: BacklashModel,
    x: np.ndarray,
    y: np.ndarray,
    *,
    output_unit: str = "",
    truth: BacklashModel | None = None,
    title: str = "Identified backlash",
) -> Figure:
    """The backlash characteristic: up and down lines of ``model`` and the path ``(x, y)``.

    ``x`` is the output of the model's linear block (it cannot be measured, so
    it comes from the model's free run) and ``y`` the measured output.
    """
    fig = _figure(figsize=(6.5, 5.5))
    ax = fig.subplots()
    ax.plot(x, y, ".", ms=2, color="0.55", alpha=0.5, label="(x-hat, measured y)")
    xs = np.linspace(float(np.min(x)), float(np.max(x)), 200)
    ax.plot(xs, xs - model.c1, color="tab:red", lw=1.6, label=f"up line  y = x - {model.c1:.4g}")
    ax.plot(xs, model.m2 * (xs + model.c2), color="tab:blue", lw=1.6,
            label=f"down line  y = {model.m2:.4g} (x + {model.c2:.4g})")  # fmt: skip
    if truth is not None:
        ax.plot(xs, xs - truth.c1, "k--", lw=0.8, label="true lines")
        ax.plot(xs, truth.m2 * (xs + truth.c2), "k--", lw=0.8)
    cross = model.lines_cross_at
    if cross is not None and xs[0] <= cross <= xs[-1]:
        ax.axvline(cross, color="0.3", ls=":", lw=1)
        ax.annotate(" lines cross", (cross, ax.get_ylim()[0]), fontsize=8, va="bottom")
    unit = f" [{output_unit}]" if output_unit else ""
    ax.set_xlabel("x (linear block output)" + unit)
    ax.set_ylabel("y (measured)" + unit)
    ax.set_title(f"{title}: dead zone c1 + c2 = {model.dead_zone:.4g}{unit}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    return fig
