"""What an identification run leaves behind: files, a summary table, a JSON object.

Shared by every way of getting a record (simulated servo, a CSV recording, a
live driver), so that all of them write the same outputs:

``recording.csv``
    The record (``t`` when known, ``u``, ``y``, plus any extra columns).
``model.json``
    The best model, versioned (:mod:`servoid.modelfile`), with the fit's
    residual RMS as the noise the smoothing band of its inverse is set for.
``convergence.png``, ``fit.png``, ``backlash.png``
    Parameter estimates against samples; measured against simulated output;
    the identified backlash loop.
``compare.png``, ``resid.png``, ``bode.png``
    What ``servoid compare`` draws, on the identification record
    (:mod:`servoid.compare_outputs`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from servoid import readings_side
from servoid.compare_outputs import COMPARE_FILES, write_compare_plots
from servoid.ident.diagnosis.compare import compare
from servoid.ident.identify import Identification
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import free_run, simulate
from servoid.ident.online.mrgia import MRGIAResult
from servoid.modelfile import ModelFile, save_model
from servoid.recording import write_recording

__all__ = ["Record", "model_content", "write_outputs", "summary_rows", "result_json", "OUTPUT_FILES"]

#: What ``write_outputs`` writes into its folder, by name: the CLI checks the places before any work.
OUTPUT_FILES = {"recording": "recording.csv", "model": "model.json", "convergence_plot": "convergence.png",
                "fit_plot": "fit.png", "backlash_plot": "backlash.png", "probe_recording": "probe.csv", **COMPARE_FILES}  # fmt: skip


@dataclass(frozen=True)
class Record:
    """A record to identify, with what is known about where it came from.

    Attributes
    ----------
    u, y : ndarray
        Input and measured output.
    source : str
        ``sim://...``, a file path or a driver URL.
    t : ndarray or None
        Sample times in seconds, when known.
    input_unit, output_unit : str
        Units of ``u`` and ``y``.
    truth : BacklashModel or None
        The true plant, for simulated records.
    servo : dict or None
        Identity reported by the driver.
    extra : dict of ndarray
        Further columns to keep in ``recording.csv`` (for example ``y_clean``).
    written_to : Path or None
        Where the record is already on disk (a live session writes as it
        measures); ``recording.csv`` is then not written again.
    valid : ndarray of bool or None
        Samples to identify from (a live record's late, missed and timed-out
        samples are False: their ``y`` may be NaN); None: all.
    acquisition : dict or None
        How a live record was sampled (rate, counts per status, driver
        counters), for the ``--json`` output.
    online : MRGIAResult or None
        The MRGIA's result of a live run over this record (the session ran it
        as the samples came); identification refines it rather than running
        the MRGIA again.
    live : dict
        What a live run adds to ``model.json`` and ``--json``: the probe, the
        design, the decimation and the online verdict (``servoid.cli._live``).
    loop : LoopChoice or None
        A live run's servo-loop answer on this record: the offline search with the
        online estimate as one more candidate (:func:`servoid.ident.online.refinement.refine_online`);
        identification takes it as its servo-loop answer (``identify(loop=)``)
        rather than fitting one again. None: not live, or no online model.
    readings : {"output", "motor"}
        Which shaft ``y`` is of (:mod:`servoid.readings_side`): the driver's, or the recording's metadata.
    """

    u: np.ndarray
    y: np.ndarray
    source: str
    t: np.ndarray | None = None
    input_unit: str = "unit"
    output_unit: str = "unit"
    truth: BacklashModel | None = None
    servo: dict[str, Any] | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    written_to: Path | None = None
    valid: np.ndarray | None = None
    acquisition: dict[str, Any] | None = None
    online: MRGIAResult | None = None
    live: dict[str, Any] = field(default_factory=dict)
    loop: Any = None
    readings: str = readings_side.OUTPUT

    @property
    def y_used(self) -> np.ndarray:
        """The measured outputs identification uses: all of ``y``, or its valid samples."""
        return self.y if self.valid is None else self.y[self.valid]

    @property
    def sample_period_s(self) -> float | None:
        if self.t is None or self.t.size < 2:
            return None
        return float(np.median(np.diff(self.t)))


def model_content(record: Record, result: Identification) -> ModelFile:
    """The ``model.json`` of an identification of ``record`` (``servoid identify`` and ``servoid batch`` write it).

    Parameters
    ----------
    record : Record
        What was identified, with its units and source.
    result : Identification
        The identification.
    """
    return ModelFile(
        model=result.model,
        stderr=result.stderr,
        input_unit=record.input_unit,
        output_unit=record.output_unit,
        sample_period_s=record.sample_period_s,
        method=result.method,
        fit_nrmse=result.fit_nrmse,
        source=record.source,
        samples=result.samples,
        servo=record.servo,
        noise_std=result.fit_nrmse * float(np.std(record.y_used)),  # the residual RMS; the band follows from it
        extra=dict(record.live),
        structure=result.structure,
        form=result.form,
        identifiable=result.identifiable,
        reason=result.reason,
        play=result.play,
        play_interval=result.play_interval,
        operating_point=(result.operating_point.u, result.operating_point.y),
        delta0=result.delta0,
        loop=None if result.loop is None else dict(result.loop.params),
    )


def write_outputs(out_dir: Path, record: Record, result: Identification, *, plots: bool = True) -> dict[str, str]:
    """Write the recording, ``model.json`` and the plots; return ``{name: path}``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths: dict[str, str] = {}
    if record.written_to is None:
        cols: dict[str, np.ndarray] = {}
        if record.t is not None:
            cols["t"] = record.t
        cols["u"] = record.u
        cols["y"] = record.y
        cols.update(record.extra)
        meta = {"servoid recording": "", "source": record.source,
                "input_unit": record.input_unit, "unit": record.output_unit}  # fmt: skip
        paths["recording"] = str(write_recording(out_dir / OUTPUT_FILES["recording"], cols, metadata=meta))
    else:
        paths["recording"] = str(record.written_to)
    paths["model"] = str(save_model(out_dir / OUTPUT_FILES["model"], model_content(record, result)))
    if plots:
        from servoid import plots as _plots

        refined = result.model if result.refinement is not None else None
        convergence = _plots.plot_convergence(result.mrgia, truth=record.truth, refined=refined)
        paths["convergence_plot"] = str(_plots.save(convergence, out_dir / OUTPUT_FILES["convergence_plot"]))
        y0 = float(record.y[0 if record.valid is None else int(np.argmax(record.valid))])
        op = result.operating_point
        u_m, y0_m = record.u - op.u, y0 - op.y  # the model's own coordinates
        d0 = result.delta0 if result.refinement is not None else None  # the refined model starts at rest
        simulated = {
            f"{result.method} (NRMSE {result.fit_nrmse:.3g})": free_run(result.model, u_m, y0=y0_m, delta0=d0) + op.y
        }
        if result.refinement is not None and result.mrgia_model is not None and result.mrgia_nrmse is not None:
            simulated[f"mrgia (NRMSE {result.mrgia_nrmse:.3g})"] = free_run(result.mrgia_model, record.u, y0=y0)
        if result.loop is not None:
            simulated[f"{result.form}, {result.structure} (NRMSE {result.loop.fit_nrmse:.3g})"] = (
                np.asarray(result.loop.simulated) + result.centred_point.y
            )
        fit = _plots.plot_fit(record.y, simulated, u=record.u, t=record.t, output_unit=record.output_unit)
        _headline(fit, result)
        paths["fit_plot"] = str(_plots.save(fit, out_dir / OUTPUT_FILES["fit_plot"]))
        x_hat = simulate(result.model, u_m, y0=y0_m, delta0=d0).x
        loop = _plots.plot_backlash(
            result.model, x_hat, record.y - op.y, output_unit=record.output_unit, truth=record.truth
        )
        _headline(loop, result)
        paths["backlash_plot"] = str(_plots.save(loop, out_dir / OUTPUT_FILES["backlash_plot"]))
        name = f"identified ({result.method})"
        start = (result.delta0, (result.operating_point.u, result.operating_point.y))
        comparison = compare({name: result.model}, record.u, record.y, valid=record.valid, starts={name: start})
        paths.update(write_compare_plots(out_dir, comparison, t=record.t, sample_period_s=record.sample_period_s,
                                         input_unit=record.input_unit, output_unit=record.output_unit))  # fmt: skip
    return paths


def _headline(fig: Any, result: Identification) -> None:
    """The structure and the verdict above a figure's own titles (the issue: named in the plots' titles)."""
    import textwrap

    lines = textwrap.wrap(result.headline(), 110)
    fig.set_layout_engine(None)
    fig.subplots_adjust(top=1.0 - 0.03 * (len(lines) + 2))
    fig.suptitle("\n".join(lines), fontsize=8, y=0.995, color="black" if result.identifiable else "firebrick")


def summary_rows(result: Identification, truth: BacklashModel | None) -> tuple[list[str], list[list[str]]]:
    """Columns and rows of the parameter table (values in the record's units): :meth:`Identification.table`."""
    return result.table(truth)


def twin_truth(record: Record) -> dict[str, Any] | None:
    """What is true of a simulated twin the record came from (its play, encoders, loop), if it did."""
    twin = (record.servo or {}).get("twin")
    return twin if isinstance(twin, dict) else None


def result_json(record: Record, result: Identification, paths: dict[str, str]) -> dict[str, Any]:
    """The ``--json`` object of ``servoid identify``."""
    out: dict[str, Any] = {
        **result.to_dict(),
        "source": record.source,
        "units": {"input": record.input_unit, "output": record.output_unit},
        "outputs": paths,
    }
    if record.acquisition is not None:
        out["acquisition"] = record.acquisition
    out.update(record.live)
    twin = twin_truth(record)
    if twin is not None:
        out["twin_truth"] = twin
    if record.truth is not None:
        out["truth"] = record.truth.to_dict()
        out["max_relative_error"] = result.model.max_relative_error(record.truth)
        if result.mrgia_model is not None:
            out["mrgia"]["max_relative_error"] = result.mrgia_model.max_relative_error(record.truth)
    return out
