"""Figures of a compensation study: tracking with and without the inverse, and robustness."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from servoid.ident.control.compensation_study import ARMS, CompensationStudy
from servoid.plots._base import figure as _figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_tracking", "plot_robustness"]

_COLOURS = {"uncompensated": "tab:red", "naive": "tab:orange", "compensated": "tab:blue"}


def plot_tracking(study: CompensationStudy, *, output_unit: str = "") -> Figure:
    """One column per reference path: the output with and without the inverse, and the errors.

    Top row: the reference (dashed) and the servo's output, uncompensated and
    with the smoothed inverse. Bottom row: the tracking errors ``r - y`` of
    all three arms (the naive inverse too), with the encoder step shaded.
    """
    cols = len(study.comparisons)
    fig = _figure(figsize=(3.6 * cols, 5.6))
    axes = fig.subplots(2, cols, sharex="col", squeeze=False)
    unit = f" [{output_unit}]" if output_unit else ""
    for j, comp in enumerate(study.comparisons):
        top, bottom = axes[0, j], axes[1, j]
        r = comp.reference.values
        k = np.arange(r.size)
        top.plot(k, r, "k--", lw=1.0, label="reference")
        for arm in ("uncompensated", "compensated"):
            top.plot(k, comp.run(arm).y, color=_COLOURS[arm], lw=1.1, label=arm)
        top.set_title(comp.reference.name, fontsize=9)
        for arm in ARMS:
            run = comp.run(arm)
            bottom.plot(k, run.reference - run.y, color=_COLOURS[arm], lw=0.9,
                        label=f"{arm} (RMS {run.metrics.rms_error:.2g})")  # fmt: skip
        if study.sensor.resolution > 0.0:
            bottom.axhspan(-study.peak_floor, study.peak_floor, color="0.85", zorder=0)
        bottom.set_xlabel("sample k")
        bottom.legend(fontsize=6, loc="upper right")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("output y" + unit)
    axes[1, 0].set_ylabel("error r - y" + unit)
    axes[0, 0].legend(fontsize=7, loc="lower left")
    fig.suptitle(
        f"Tracking on the simulated servo: same controller (feedforward, k_i = {study.integral_gain:.3g}), "
        f"without and with the backlash inverse (band {study.band:.3g}{unit})",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def plot_robustness(study: CompensationStudy, *, output_unit: str = "") -> Figure:
    """RMS error and motor travel of each arm, nominal and with the controller's model perturbed.

    Bars on a log scale, one group per model; the dotted line is the RMS of
    the encoder's quantisation (what the servo cannot resolve).
    """
    rows = [("nominal", {arm: study.summary(arm) for arm in ARMS})]
    rows += [(p.label, p.summaries) for p in study.perturbations if p.summaries]
    labels = [label for label, _ in rows]
    x = np.arange(len(rows))
    width = 0.27
    fig = _figure(figsize=(max(8.0, 1.1 * len(rows)), 6.4))
    ax_rms, ax_travel = fig.subplots(2, 1, sharex=True)
    for i, arm in enumerate(ARMS):
        rms = [s[arm].rms_error for _, s in rows]
        travel = [s[arm].motor_travel for _, s in rows]
        ax_rms.bar(x + (i - 1) * width, rms, width, color=_COLOURS[arm], label=arm)
        ax_travel.bar(x + (i - 1) * width, travel, width, color=_COLOURS[arm], label=arm)
    if study.rms_floor > 0.0:
        ax_rms.axhline(study.rms_floor, color="k", ls=":", lw=1, label="quantisation floor q/sqrt(12)")
    unit = f" [{output_unit}]" if output_unit else ""
    ax_rms.set_yscale("log")
    ax_rms.set_ylabel("RMS tracking error" + unit)
    ax_rms.legend(fontsize=8, ncol=4, loc="lower center", bbox_to_anchor=(0.5, 1.0), frameon=False)
    ax_travel.set_yscale("log")
    ax_travel.set_ylabel("motor travel / reference travel")
    ax_travel.set_xticks(x)
    ax_travel.set_xticklabels(labels, rotation=30, ha="right", fontsize=8)
    for ax in (ax_rms, ax_travel):
        ax.grid(alpha=0.3, axis="y", which="both")
    fig.suptitle("Robustness: the controller's model perturbed, the simulated servo unchanged")
    fig.tight_layout()
    return fig
