"""Figures (matplotlib, imported lazily, no screen needed), one module per topic.

Every function takes result objects, draws, writes a PNG and returns its path.
Shared helpers: :func:`pyplot` (matplotlib with the Agg backend) and
:func:`save`.
"""

from servoid.plots._base import pyplot, save
from servoid.plots.compensation import plot_robustness, plot_tracking
from servoid.plots.diagnose import plot_candidates, plot_diagnosis_fit, plot_regimes, plot_residual_tests
from servoid.plots.identify import plot_backlash, plot_convergence, plot_fit

__all__ = [
    "pyplot",
    "save",
    "plot_convergence",
    "plot_fit",
    "plot_backlash",
    "plot_diagnosis_fit",
    "plot_regimes",
    "plot_residual_tests",
    "plot_candidates",
    "plot_tracking",
    "plot_robustness",
]
