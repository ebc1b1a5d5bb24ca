"""What a diagnosis leaves behind: the extended model, plots, a JSON object, a summary table.

``model.json``
    The final model: the base under ``"model"``, the effects under
    ``"effects"`` (:mod:`servoid.extendedfile`).
``diagnose_fit.png``, ``diagnose_regimes.png``, ``diagnose_resid.png``, ``diagnose_candidates.png``
    Measured against both models and the residuals; the regime breakdown;
    the ``resid`` checks; the validation gap of every candidate.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from servoid.extendedfile import save_extended_model
from servoid.ident.diagnosis.diagnose import Diagnosis
from servoid.recording import Recording

__all__ = ["write_diagnosis_outputs", "diagnosis_json", "candidate_rows", "DIAGNOSE_FILES"]

#: What ``write_diagnosis_outputs`` writes into its folder, by name.
DIAGNOSE_FILES = {"model": "model.json", "fit_plot": "diagnose_fit.png", "regimes_plot": "diagnose_regimes.png",
                  "resid_plot": "diagnose_resid.png", "candidates_plot": "diagnose_candidates.png"}  # fmt: skip


def write_diagnosis_outputs(out_dir: Path, diagnosis: Diagnosis, train: Recording, validate: Recording, *,
                            source: str, input_unit: str, output_unit: str, plots: bool = True) -> dict[str, str]:  # fmt: skip
    """Write ``model.json`` and the plots into ``out_dir``; return ``{name: path}``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "model": str(save_extended_model(
            out_dir / DIAGNOSE_FILES["model"], diagnosis.model, method="mrgia+oe+effects", fit_nrmse=diagnosis.gap_after,
            source=source, samples=len(train), input_unit=input_unit, output_unit=output_unit,
            sample_period_s=train.sample_period,
        ))
    }  # fmt: skip
    if plots:
        from servoid import plots as _plots

        figures = {
            "fit_plot": _plots.plot_diagnosis_fit(diagnosis, validate.y, t=validate.t, output_unit=output_unit),
            "regimes_plot": _plots.plot_regimes(diagnosis),
            "resid_plot": _plots.plot_residual_tests(diagnosis),
            "candidates_plot": _plots.plot_candidates(diagnosis),
        }
        for key, fig in figures.items():
            paths[key] = str(_plots.save(fig, out_dir / DIAGNOSE_FILES[key]))
    return paths


def diagnosis_json(diagnosis: Diagnosis, paths: dict[str, str], *, units: dict[str, str]) -> dict[str, Any]:
    """The ``--json`` object of ``servoid diagnose``: the diagnosis's own dict, its units and outputs."""
    return {**diagnosis.to_dict(), "units": units, "outputs": paths}


def candidate_rows(diagnosis: Diagnosis) -> tuple[list[str], list[list[str]]]:
    """Columns and rows of the candidate table (every round)."""
    cols = ["round", "effect", "parameters", "train", "validation", "score", ""]
    rows = []
    for i, rnd in enumerate(diagnosis.rounds):
        for c in rnd.candidates:
            params = ", ".join(f"{k}={v:.4g}" for k, v in c.parameters.items()) or "-"
            rows.append([str(i + 1), c.effect, params, f"{c.train_nrmse:.4g}", f"{c.gap:.4g}", f"{c.score:.4g}",
                         "<- chosen" if c is rnd.chosen else ""])  # fmt: skip
    return cols, rows
