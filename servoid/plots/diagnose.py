"""Figures of a diagnosis: measured against both models, residuals, regimes, resid checks, candidates."""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING

import numpy as np

from servoid.ident.diagnosis.diagnose import Diagnosis
from servoid.ident.diagnosis.residuals import GROUPS
from servoid.plots._base import figure as _figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_diagnosis_fit", "plot_regimes", "plot_residual_tests", "plot_candidates"]


def _labels(diagnosis: Diagnosis) -> tuple[str, str]:
    before = f"base model (gap {diagnosis.gap_before:.3g})"
    after = f"{' + '.join(diagnosis.effects) or 'no effect added'} (gap {diagnosis.gap_after:.3g})"
    return before, after


def plot_diagnosis_fit(
    diagnosis: Diagnosis,
    y: np.ndarray,
    *,
    t: np.ndarray | None = None,
    window: int = 400,
    output_unit: str = "",
) -> Figure:
    """Validation record: measured against both models (a window), and the residual of each over the record.

    The window is placed where the base model's error is largest, so the
    plot shows what the added effect fixes.
    """
    y_arr = np.asarray(y, dtype=float)
    n = y_arr.size
    axis = np.arange(n) if t is None else np.asarray(t, dtype=float)
    xlabel = "sample k" if t is None else "time [s]"
    unit = f" [{output_unit}]" if output_unit else ""
    before, after = diagnosis.validation_before.y, diagnosis.validation_after.y
    r_before, r_after = y_arr - before, y_arr - after
    w = min(window, n)
    # Centre the window on the largest running error energy of the base model.
    energy = np.convolve(r_before**2, np.ones(w), mode="valid")
    lo = int(np.argmax(energy)) if energy.size else 0
    sl = slice(lo, lo + w)
    lab_b, lab_a = _labels(diagnosis)
    fig = _figure(figsize=(10, 8))
    axes = fig.subplots(3, 1)
    ax = axes[0]
    ax.plot(axis[sl], y_arr[sl], color="k", lw=1.4, label="measured")
    ax.plot(axis[sl], before[sl], color="tab:orange", lw=1.0, label=lab_b)
    ax.plot(axis[sl], after[sl], color="tab:blue", lw=1.0, ls="--", label=lab_a)
    ax.set_ylabel("y" + unit)
    ax.set_title(f"validation record, free run: the {w} samples where the base model is worst")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[1]
    ax.plot(axis[sl], r_before[sl], color="tab:orange", lw=0.8, label="before")
    ax.plot(axis[sl], r_after[sl], color="tab:blue", lw=0.8, label="after")
    ax.set_ylabel("y - y_hat" + unit)
    ax.set_title("residual, same window")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[2]
    ax.plot(axis, r_before, color="tab:orange", lw=0.5, label="before")
    ax.plot(axis, r_after, color="tab:blue", lw=0.5, label="after")
    ax.axvspan(axis[lo], axis[min(lo + w, n) - 1], color="0.85", zorder=0)
    ax.set_ylabel("y - y_hat" + unit)
    ax.set_xlabel(xlabel)
    ax.set_title("residual, whole validation record (shaded: the window above)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot_regimes(diagnosis: Diagnosis) -> Figure:
    """Where the error lies: for each regime, its share of the samples and of the error energy, before and after."""
    fig = _figure(figsize=(13, 8.5))
    axes = fig.subplots(2, 3)
    flat = axes.ravel()
    for ax, group in zip(flat, GROUPS):
        before = diagnosis.breakdown_before.group(group)
        after = {r.label: r for r in diagnosis.breakdown_after.group(group)}
        labels = [r.label.replace(" after a reversal", "\nafter reversal") for r in before]
        pos = np.arange(len(before))
        ax.bar(pos - 0.27, [100 * r.sample_share for r in before], 0.27, color="0.7", label="samples")
        ax.bar(pos, [100 * r.energy_share for r in before], 0.27, color="tab:orange", label="error energy, before")
        ax.bar(pos + 0.27, [100 * after[r.label].energy_share if r.label in after else 0.0 for r in before], 0.27,
               color="tab:blue", label="error energy, after")  # fmt: skip
        ax.set_xticks(pos)
        ax.set_xticklabels(labels, rotation=35, ha="right", fontsize=7)
        ax.set_title(group)
        ax.set_ylabel("share [%]")
        ax.grid(alpha=0.3, axis="y")
    flat[0].legend(fontsize=7)
    text = flat[len(GROUPS)]
    text.axis("off")
    notes = [
        "where the base model's error lies (validation):",
        *textwrap.wrap(diagnosis.where, 55),
        "",
        "base model:",
        *textwrap.wrap(diagnosis.resid_before.summary(), 55),
        "",
        f"after adding {' + '.join(diagnosis.effects) or 'nothing'}:",
        *textwrap.wrap(diagnosis.resid_after.summary(), 55),
        "",
        f"validation gap {diagnosis.gap_before:.3g} -> {diagnosis.gap_after:.3g}",
    ]
    text.text(0.0, 1.0, "\n".join(notes), va="top", fontsize=8.5, family="monospace")
    fig.suptitle("share of the samples and of the error energy, by regime", fontsize=11)
    fig.tight_layout()
    return fig


def plot_residual_tests(diagnosis: Diagnosis) -> Figure:
    """``resid``-style checks: residual autocorrelation and cross-correlation with past inputs, with the band."""
    fig = _figure(figsize=(9, 6))
    axes = fig.subplots(2, 1, sharex=True)
    for ax, attr, title in ((axes[0], "autocorrelation", "residual autocorrelation"),
                            (axes[1], "cross_correlation", "cross-correlation of the residual with u(k - lag)")):  # fmt: skip
        for tests, colour, label, shift in ((diagnosis.resid_before, "tab:orange", "before", -0.15),
                                            (diagnosis.resid_after, "tab:blue", "after", 0.15)):  # fmt: skip
            values = getattr(tests, attr)
            lags = tests.lags
            start = 1 if attr == "autocorrelation" else 0
            ax.vlines(lags[start:] + shift, 0, values[start:], color=colour, lw=2, label=label)
        band = diagnosis.resid_after.band
        ax.axhspan(-band, band, color="0.85", zorder=0,
                   label=f"{100 * diagnosis.resid_after.confidence:.0f} % band")  # fmt: skip
        ax.axhline(0, color="k", lw=0.6)
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[1].set_xlabel("lag [samples]")
    fig.tight_layout()
    return fig


def plot_candidates(diagnosis: Diagnosis) -> Figure:
    """Validation gap of each candidate of each round, and the score threshold that ``none`` sets."""
    rounds = diagnosis.rounds
    fig = _figure(figsize=(5.5 * len(rounds), 3.8))
    axes = fig.subplots(1, len(rounds), squeeze=False)
    for i, (ax, rnd) in enumerate(zip(axes[0], rounds)):
        names = [c.effect for c in rnd.candidates]
        gaps = [c.gap for c in rnd.candidates]
        colours = ["tab:green" if c is rnd.chosen else "0.6" for c in rnd.candidates]
        ax.barh(np.arange(len(names)), gaps, color=colours)
        none = rnd.candidates[0]
        ax.axvline(none.gap / (1 + diagnosis.config.penalty), color="tab:red", ls="--", lw=1,
                   label="a 1-parameter effect must beat this")  # fmt: skip
        ax.set_yticks(np.arange(len(names)))
        ax.set_yticklabels(names, fontsize=8)
        ax.set_xscale("log")
        ax.set_xlabel("validation gap (free-run NRMSE)")
        ax.set_title(f"round {i + 1}: chosen {rnd.chosen.effect}", fontsize=9)
        ax.grid(alpha=0.3, axis="x", which="both")
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
