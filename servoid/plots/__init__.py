"""Figures (matplotlib, imported lazily, no screen needed), one module per topic.

Every function takes result objects, draws and returns a
:class:`matplotlib.figure.Figure`; :func:`save` writes one as PNG. No
function picks or switches matplotlib's backend (the figures are made
without pyplot): in a notebook a figure shows as the cell's value and the
session's backend stays what it was.
"""

from servoid.plots._base import figure, save
from servoid.plots.compare import plot_compare, plot_linear_block, plot_resid
from servoid.plots.compensation import plot_robustness, plot_tracking
from servoid.plots.diagnose import plot_candidates, plot_diagnosis_fit, plot_regimes, plot_residual_tests
from servoid.plots.identify import plot_backlash, plot_convergence, plot_fit

__all__ = [
    "figure",
    "save",
    "plot_convergence",
    "plot_fit",
    "plot_backlash",
    "plot_compare",
    "plot_resid",
    "plot_linear_block",
    "plot_diagnosis_fit",
    "plot_regimes",
    "plot_residual_tests",
    "plot_candidates",
    "plot_tracking",
    "plot_robustness",
]
