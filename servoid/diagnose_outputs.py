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

import numpy as np

from servoid.extendedfile import save_extended_model
from servoid.ident.diagnosis.diagnose import Candidate, Diagnosis
from servoid.ident.models.effects import EFFECTS
from servoid.ident.diagnosis.residuals import RegimeBreakdown, ResidualTests
from servoid.recording import Recording

__all__ = ["write_diagnosis_outputs", "diagnosis_json", "candidate_rows"]


def write_diagnosis_outputs(out_dir: Path, diagnosis: Diagnosis, train: Recording, validate: Recording, *,
                            source: str, input_unit: str, output_unit: str, plots: bool = True) -> dict[str, str]:  # fmt: skip
    """Write ``model.json`` and the plots into ``out_dir``; return ``{name: path}``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "model": str(save_extended_model(
            out_dir / "model.json", diagnosis.model, method="mrgia+oe+effects", fit_nrmse=diagnosis.gap_after,
            source=source, samples=len(train), input_unit=input_unit, output_unit=output_unit,
            sample_period_s=train.sample_period,
        ))
    }  # fmt: skip
    if plots:
        from servoid import plots as _plots

        paths["fit_plot"] = str(_plots.plot_diagnosis_fit(diagnosis, validate.y, out_dir / "diagnose_fit.png",
                                                          t=validate.t, output_unit=output_unit))  # fmt: skip
        paths["regimes_plot"] = str(_plots.plot_regimes(diagnosis, out_dir / "diagnose_regimes.png"))
        paths["resid_plot"] = str(_plots.plot_residual_tests(diagnosis, out_dir / "diagnose_resid.png"))
        paths["candidates_plot"] = str(_plots.plot_candidates(diagnosis, out_dir / "diagnose_candidates.png"))
    return paths


def _candidate(c: Candidate) -> dict[str, Any]:
    return {"effect": c.effect, "gap": c.gap, "score": c.score, "train_nrmse": c.train_nrmse,
            "extra_parameters": c.extra_parameters, "parameters": c.parameters}  # fmt: skip


def _breakdown(b: RegimeBreakdown) -> list[dict[str, Any]]:
    return [{"group": r.group, "regime": r.label, "sample_share": r.sample_share, "energy_share": r.energy_share,
             "rms": r.rms, "mean": r.mean} for r in b.regimes]  # fmt: skip


def _tests(t: ResidualTests) -> dict[str, Any]:
    return {
        "confidence": t.confidence, "band": t.band, "white": t.white, "independent_of_input": t.independent_of_input,
        "autocorrelation_outside": t.autocorrelation_outside, "cross_correlation_outside": t.cross_correlation_outside,
        "autocorrelation": np.round(t.autocorrelation, 6).tolist(),
        "cross_correlation": np.round(t.cross_correlation, 6).tolist(),
    }  # fmt: skip


def diagnosis_json(diagnosis: Diagnosis, paths: dict[str, str], *, units: dict[str, str]) -> dict[str, Any]:
    """The ``--json`` object of ``servoid diagnose``.

    The keys the issue fixes come first: ``effect``, ``effect_parameters``,
    ``where``, ``gap_before``, ``gap_after`` (validation NRMSEs) and
    ``candidates`` (the first round: every effect tried on the base model).
    """
    return {
        "effect": diagnosis.effect,
        "effect_parameters": diagnosis.effect_parameters,
        "where": diagnosis.where,
        "gap_before": diagnosis.gap_before,
        "gap_after": diagnosis.gap_after,
        "candidates": [_candidate(c) for c in diagnosis.candidates],
        "effects": diagnosis.model.effects_json(),
        "rounds": [{"chosen": r.chosen.effect, "candidates": [_candidate(c) for c in r.candidates]}
                   for r in diagnosis.rounds],  # fmt: skip
        "model": {**diagnosis.model.base.to_dict(), "effects": diagnosis.model.effects_json()},
        "base_model": diagnosis.base.base.to_dict(),
        "parameter_units": {name: dict(zip(e.parameters, e.units)) for name, e in EFFECTS.items()},
        "units": units,
        "penalty": diagnosis.config.penalty,
        "regimes_before": _breakdown(diagnosis.breakdown_before),
        "regimes_after": _breakdown(diagnosis.breakdown_after),
        "residual_tests_before": _tests(diagnosis.resid_before),
        "residual_tests_after": _tests(diagnosis.resid_after),
        "warnings": list(diagnosis.identification.warnings),
        "outputs": paths,
    }


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
