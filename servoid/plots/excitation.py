"""Figure of an excitation: the signal, its amplitude histogram, and where it puts the backlash."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from servoid.excitation.report import ExcitationReport
from servoid.ident.models.kernels import ZONE_DOWN, ZONE_MEMORY, ZONE_UP
from servoid.plots._base import figure as _figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_excitation"]

_ZONES = (
    (ZONE_UP, "up line", "y on the up line", "tab:red"),
    (ZONE_DOWN, "down line", "y on the down line", "tab:blue"),
    (ZONE_MEMORY, "memory zone", "y in the memory zone", "0.6"),
)


def plot_excitation(
    u: Sequence[float] | np.ndarray,
    report: ExcitationReport,
    *,
    bounds: tuple[float, float] | None = None,
    sample_period_s: float | None = None,
    window: int = 600,
    input_unit: str = "",
    title: str = "Excitation",
    level: str | None = None,
) -> Figure:
    """Time series, amplitude histogram and zone occupancy of an input.

    Parameters
    ----------
    u : array_like
        The input.
    report : ExcitationReport
        Its report; when it ran the input through a model, the model's ``x``
        and ``y`` are drawn too, coloured by zone, with the zone shares.
    bounds : (low, high), optional
        The amplitude bound, drawn as dashed lines.
    sample_period_s : float, optional
        Draw against time in seconds instead of samples.
    window : int
        Samples shown in the time series (from the start).
    input_unit : str
        Unit of ``u`` for the axis labels.
    title : str
        Figure title; the overall verdict is appended.
    level : str, optional
        That verdict, when it is not the report's own (a design judges only
        the verdicts that apply to its prior).
    """
    u_arr = np.asarray(u, dtype=float)
    n = min(window, u_arr.size)
    axis = np.arange(n) * (sample_period_s or 1.0)
    xlabel = "time [s]" if sample_period_s else "sample k"
    unit = f" [{input_unit}]" if input_unit else ""
    tm = report.through_model
    rows = 3 if tm is not None else 2
    fig = _figure(figsize=(10, 2.7 * rows))
    grid = fig.add_gridspec(rows, 2)
    ax = fig.add_subplot(grid[0, :])
    ax.step(axis, u_arr[:n], where="post", color="tab:green", lw=1.0)
    if bounds is not None:
        for bound in bounds:
            ax.axhline(bound, color="k", ls="--", lw=0.8)
    ax.set_ylabel("u" + unit)
    ax.set_xlabel(xlabel)
    ax.set_title(f"input, first {n} of {u_arr.size} samples")
    ax.grid(alpha=0.3)
    if tm is not None:
        sim = tm.simulation
        ax = fig.add_subplot(grid[1, :])
        ax.plot(axis, sim.x[:n], color="0.3", lw=0.8, label="x (linear block)")
        zone = sim.zone[:n]
        for code, _, legend, colour in _ZONES:
            on = zone == code
            ax.plot(axis[on], sim.y_clean[:n][on], ".", ms=3, color=colour, label=legend)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("x, y (model)")
        ax.set_title("through the model, by zone")
        ax.legend(fontsize=7, ncol=4, loc="upper right")
        ax.grid(alpha=0.3)
    ax = fig.add_subplot(grid[rows - 1, 0])
    ax.hist(u_arr, bins=min(60, max(10, u_arr.size // 50)), color="tab:green", alpha=0.8)
    if bounds is not None:
        for bound in bounds:
            ax.axvline(bound, color="k", ls="--", lw=0.8)
    ax.set_xlabel("u" + unit)
    ax.set_ylabel("samples")
    ax.set_title(f"amplitude histogram (crest factor {report.signal.crest_factor:.3g})")
    ax = fig.add_subplot(grid[rows - 1, 1])
    if tm is not None:
        shares = (tm.share_up, tm.share_down, tm.share_memory)
        labels = [label for _, label, _, _ in _ZONES]
        bars = ax.bar(labels, [100 * s for s in shares], color=[c for _, _, _, c in _ZONES])
        ax.bar_label(bars, fmt="%.0f%%", fontsize=8)
        ax.set_ylabel("% of samples")
        ax.set_ylim(0, 100)
        ax.set_title(f"zone occupancy, {tm.line_switches} crossings of the play")
    else:
        order = np.arange(1, len(report.signal.pe_condition) + 1)
        ax.semilogy(order, report.signal.pe_condition, "o-", color="tab:purple")
        ax.set_xlabel("order m")
        ax.set_ylabel("condition of R_m")
        ax.set_title(f"persistent excitation: order {report.signal.pe_order}")
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(f"{title}: {level or report.level}")
    fig.tight_layout()
    return fig
