"""The figures of a comparison, written where a command writes its plots: ``servoid compare`` and ``servoid identify``.

``compare.png``
    Measured output against each model's free run (fit %), residuals, left-out samples shaded.
``resid.png``
    The residual's autocorrelation and cross-correlation with the input, with the 99 % band.
``bode.png``
    Bode and unit-step response of each model's linear block, with the play.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from servoid.ident.diagnosis.compare import Comparison
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["COMPARE_FILES", "write_compare_plots", "coloured_warnings"]

#: The figures, by name (a suffix ``-N`` is put before ``.png`` for the N-th record of several).
COMPARE_FILES = {"compare_plot": "compare.png", "resid_plot": "resid.png", "bode_plot": "bode.png"}


def _named(name: str, suffix: str) -> str:
    stem, dot, ext = name.rpartition(".")
    return f"{stem}{suffix}{dot}{ext}"


def write_compare_plots(
    out_dir: Path,
    comparison: Comparison,
    *,
    t: np.ndarray | None = None,
    sample_period_s: float | None = None,
    input_unit: str = "",
    output_unit: str = "",
    suffix: str = "",
    bode: bool = True,
) -> dict[str, str]:
    """Write ``compare.png``, ``resid.png`` and (with ``bode``) ``bode.png`` into ``out_dir``; return ``{name: path}``.

    Parameters
    ----------
    out_dir : Path
        The folder (created if needed).
    comparison : Comparison
        The models' free runs on one record.
    t : ndarray, optional
        The record's sample times, seconds.
    sample_period_s : float, optional
        For the Bode and step axes (Hz, seconds).
    input_unit, output_unit : str
        Units, for labels.
    suffix : str
        Put before ``.png`` in the compare and resid file names (several records).
    bode : bool
        Also write the Bode and step figure (once, not per record).
    """
    from servoid import plots

    models: Mapping[str, BacklashModel] = {fit.name: fit.model for fit in comparison.fits}
    figures = {
        "compare_plot": (plots.plot_compare(comparison, t=t, output_unit=output_unit), suffix),
        "resid_plot": (plots.plot_resid(comparison), suffix),
    }
    if bode:
        fig = plots.plot_linear_block(models, sample_period_s=sample_period_s, input_unit=input_unit,
                                      output_unit=output_unit)  # fmt: skip
        figures["bode_plot"] = (fig, "")
    return {key: str(plots.save(fig, out_dir / _named(COMPARE_FILES[key], sfx))) for key, (fig, sfx) in figures.items()}


def coloured_warnings(comparison: Comparison) -> list[str]:
    """One line for each model whose residual is coloured (it fails the Ljung-Box test: ``ModelFit.coloured``)."""
    return [w for w in (fit.coloured_warning() for fit in comparison.fits) if w is not None]
