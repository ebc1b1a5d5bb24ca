"""Proof by simulation: does the backlash inverse help, and how wrong may the model be?

:func:`compensation_study` drives the simulated servo (the true model) along
the paths of :func:`~servoid.ident.control.references.reference_suite` with three
arms of the same :class:`~servoid.ident.control.tracking.TrackingController` (same
model, feedforward and integral gain):

``uncompensated``  the backlash ignored
``naive``          the inverse with band 0 (a direction-change offset)
``compensated``    the inverse with the smoothing band

then repeats it with the controller's model perturbed (dead zones only, and
every parameter) by the given relative changes, the servo staying the same.

Ratios are stated against the encoder resolution: an RMS error below the
quantisation floor ``q / sqrt(12)`` cannot be measured on the servo, so a
ratio whose compensated error is below it is floored there and flagged as
a lower bound.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from servoid import validation
from servoid.errors import ModelError
from servoid.ident.control.compensate import InverseParams
from servoid.ident.control.references import Reference, reference_suite
from servoid.ident.control.tracking import LoopDiverged, Sensor, TrackingController, TrackingRun, simulate_tracking
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = [
    "ARMS",
    "CHANGES",
    "FAMILIES",
    "Arm",
    "Family",
    "Comparison",
    "ArmSummary",
    "Improvement",
    "Perturbation",
    "CompensationStudy",
    "perturbed",
    "default_resolution",
    "compensation_study",
]

Arm = Literal["uncompensated", "naive", "compensated"]
Family = Literal["dead zones", "all parameters"]

ARMS: tuple[Arm, ...] = ("uncompensated", "naive", "compensated")
#: Relative perturbations of the controller's model in the robustness study.
CHANGES: tuple[float, ...] = (-0.2, -0.1, 0.1, 0.2)
FAMILIES: tuple[Family, ...] = ("dead zones", "all parameters")
_FAMILY_SHORT = {"dead zones": "c1,c2", "all parameters": "all"}

#: The simulated encoder's step relative to the dead zone, when the unit is not counts.
_RESOLUTION_SHARE = 1.0 / 200.0

#: Dead time counts once the output has travelled this share of the path's span...
_TURN_SHARE = 0.02
#: ...and at least this many encoder steps and noise standard deviations.
_TURN_STEPS, _TURN_SIGMAS = 2.0, 4.0


def default_resolution(model: BacklashModel, output_unit: str = "") -> float:
    """The simulated encoder's step: one count for a model in counts, else ``(c1 + c2) / 200``.

    The play is then 200 encoder steps wide (a hobby servo with 1 degree of
    play and a 12-bit encoder has about 11, an industrial gearhead with
    arc-minutes of play and a 20-bit encoder thousands); the compensated
    error cannot be resolved below one step, so set the real one with
    ``--resolution``.
    """
    if output_unit.strip().lower() in ("count", "counts", "cnt", "ticks"):
        return 1.0
    return _RESOLUTION_SHARE * model.dead_zone


def perturbed(model: BacklashModel, family: Family, change: float) -> BacklashModel:
    """``model`` with parameters scaled by ``1 + change``.

    ``"dead zones"`` scales ``c1`` and ``c2``; ``"all parameters"`` scales every
    ``a_i``, ``b_j``, ``m2``, ``c1`` and ``c2`` (the delay stays).

    Raises
    ------
    ModelError
        If the scaled model is invalid (an unstable linear block).
    """
    f = 1.0 + validation.real("change", change)
    if family == "dead zones":
        return BacklashModel(a=model.a, b=model.b, delay=model.delay, m2=model.m2, c1=model.c1 * f, c2=model.c2 * f)
    if family == "all parameters":
        return BacklashModel(
            a=tuple(v * f for v in model.a), b=tuple(v * f for v in model.b), delay=model.delay,
            m2=model.m2 * f, c1=model.c1 * f, c2=model.c2 * f,
        )  # fmt: skip
    raise ModelError(f"family (={family!r}) must be one of {', '.join(map(repr, FAMILIES))}")


@dataclass(frozen=True)
class Comparison:
    """The three arms on one reference path."""

    reference: Reference
    uncompensated: TrackingRun
    naive: TrackingRun
    compensated: TrackingRun

    def run(self, arm: Arm) -> TrackingRun:
        """The run of one arm."""
        return getattr(self, arm)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class ArmSummary:
    """One arm over all the paths.

    Attributes
    ----------
    rms_error : float
        RMS of ``r - y`` over every sample of every path (output unit).
    peak_error : float
        Largest ``|r - y|`` (output unit).
    dead_time : float
        Mean dead time after reversals (samples).
    motor_travel : float
        Travel of the backlash input per unit of reference travel, all paths.
    """

    rms_error: float
    peak_error: float
    dead_time: float
    motor_travel: float

    def to_dict(self) -> dict[str, Any]:
        """``{"rms_error", "peak_error", "dead_time_samples", "motor_travel"}`` (null travel: no reference travel)."""
        return {"rms_error": self.rms_error, "peak_error": self.peak_error, "dead_time_samples": self.dead_time,
                "motor_travel": self.motor_travel}  # fmt: skip

    @classmethod
    def of(cls, runs: Sequence[TrackingRun]) -> ArmSummary:
        err = np.concatenate([r.reference - r.y for r in runs])
        turns = sum(r.metrics.reversals for r in runs)
        dead = sum(r.metrics.dead_time * r.metrics.reversals for r in runs)
        path = sum(float(np.sum(np.abs(np.diff(r.reference)))) for r in runs)
        motor = sum(float(np.sum(np.abs(np.diff(r.x)))) for r in runs)
        return cls(
            rms_error=float(np.sqrt(np.mean(err**2))),
            peak_error=float(np.max(np.abs(err))),
            dead_time=dead / turns if turns else 0.0,
            motor_travel=motor / path if path > 0.0 else float("nan"),
        )


@dataclass(frozen=True)
class Improvement:
    """``before / after``, with ``after`` floored at what the sensor can resolve.

    Attributes
    ----------
    ratio : float
        ``before / max(after, floor)``.
    at_floor : bool
        Whether ``after`` was below the floor (the ratio is then a lower bound).
    """

    ratio: float
    at_floor: bool

    @classmethod
    def of(cls, before: float, after: float, floor: float) -> Improvement:
        denominator = max(after, floor)
        if denominator == 0.0:
            return cls(ratio=math.inf, at_floor=True)
        return cls(ratio=before / denominator, at_floor=after < floor)

    def __str__(self) -> str:
        return f"{'>=' if self.at_floor else ''}{self.ratio:.3g}x"


@dataclass(frozen=True)
class Perturbation:
    """The arms over all paths with the controller's model perturbed.

    Attributes
    ----------
    family : {"dead zones", "all parameters"}
        What was scaled.
    change : float
        Relative change (``0.1`` is +10 %).
    model : BacklashModel or None
        The controller's model, ``None`` when the scaled model is invalid.
    summaries : dict
        ``{arm: ArmSummary}``; empty when the model is invalid or a closed
        loop with it diverged.
    note : str
        Why the row is empty, if it is.
    """

    family: Family
    change: float
    model: BacklashModel | None
    summaries: dict[Arm, ArmSummary]
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """``{"family", "change", "note", <arm>: ArmSummary.to_dict(), ...}``."""
        return {"family": self.family, "change": self.change, "note": self.note,
                **{arm: s.to_dict() for arm, s in self.summaries.items()}}  # fmt: skip

    @property
    def label(self) -> str:
        """``"c1,c2 +10%"`` or ``"all +10%"``."""
        return f"{_FAMILY_SHORT[self.family]} {self.change * 100:+.0f}%"


@dataclass(frozen=True)
class CompensationStudy:
    """Result of :func:`compensation_study`.

    Attributes
    ----------
    plant : BacklashModel
        The simulated servo.
    model : BacklashModel
        The controller's nominal model.
    band : float
        Smoothing band of the compensated arm (output unit).
    integral_gain : float
        ``k_i`` of every arm (per sample).
    preview : int
        Samples of the reference the feedforward looks ahead.
    sensor : Sensor
        Resolution and noise of the simulated measurement.
    comparisons : tuple of Comparison
        Nominal model, one per path.
    perturbations : tuple of Perturbation
        The robustness study.
    """

    plant: BacklashModel
    model: BacklashModel
    band: float
    integral_gain: float
    preview: int
    sensor: Sensor
    comparisons: tuple[Comparison, ...]
    perturbations: tuple[Perturbation, ...]

    @property
    def rms_floor(self) -> float:
        """RMS of the encoder's quantisation error, ``q / sqrt(12)`` (output unit)."""
        return self.sensor.resolution / math.sqrt(12.0)

    @property
    def peak_floor(self) -> float:
        """Half an encoder step (output unit)."""
        return self.sensor.resolution / 2.0

    def summary(self, arm: Arm) -> ArmSummary:
        """One arm over all paths, nominal model."""
        return ArmSummary.of([c.run(arm) for c in self.comparisons])

    def to_dict(self) -> dict[str, Any]:
        """For JSON: the settings, each path's metrics per arm, all paths per arm, the robustness rows.

        ``rms_ratio`` (uncompensated over compensated) is null when the
        compensated error is zero; ``rms_ratio_at_floor`` says whether that arm
        reached the sensor's floor (the ratio is then a lower bound).
        """
        nominal = []
        for comp in self.comparisons:
            entry: dict[str, Any] = {"reference": comp.reference.name}
            for arm in ARMS:
                run = comp.run(arm)
                m = run.metrics
                entry[arm] = {"rms_error": m.rms_error, "peak_error": m.peak_error, "dead_time_samples": m.dead_time,
                              "dead_time_max_samples": m.dead_time_max, "reversals": m.reversals,
                              "motor_travel": run.motor_travel}  # fmt: skip
            entry["rms_ratio"] = self.rms_improvement(comp.uncompensated, comp.compensated).ratio
            nominal.append(entry)
        overall = self.rms_improvement(self.summary("uncompensated"), self.summary("compensated"))
        return {
            "band": self.band, "integral_gain": self.integral_gain, "preview_samples": self.preview,
            "resolution": self.sensor.resolution, "noise_std": self.sensor.noise_std, "rms_floor": self.rms_floor,
            "nominal": nominal, "all_paths": {arm: self.summary(arm).to_dict() for arm in ARMS},
            "rms_ratio": overall.ratio, "rms_ratio_at_floor": overall.at_floor,
            "perturbations": [p.to_dict() for p in self.perturbations],
        }  # fmt: skip

    def rms_improvement(self, before: ArmSummary | TrackingRun, after: ArmSummary | TrackingRun) -> Improvement:
        """RMS error ratio ``before / after``, floored at the quantisation floor."""
        return Improvement.of(_rms(before), _rms(after), self.rms_floor)

    def peak_improvement(self, before: ArmSummary | TrackingRun, after: ArmSummary | TrackingRun) -> Improvement:
        """Peak error ratio ``before / after``, floored at half an encoder step."""
        return Improvement.of(_peak(before), _peak(after), self.peak_floor)


def _rms(item: ArmSummary | TrackingRun) -> float:
    return item.rms_error if isinstance(item, ArmSummary) else item.metrics.rms_error


def _peak(item: ArmSummary | TrackingRun) -> float:
    return item.peak_error if isinstance(item, ArmSummary) else item.metrics.peak_error


def _arms(
    plant: BacklashModel,
    model: BacklashModel,
    references: Sequence[Reference],
    *,
    band: float,
    integral_gain: float | None,
    sensor: Sensor,
) -> list[Comparison]:
    inverses: dict[Arm, InverseParams | None] = {
        "uncompensated": None,
        "naive": InverseParams.from_model(model, band=0.0),
        "compensated": InverseParams.from_model(model, band=band),
    }
    out = []
    for ref in references:
        threshold = max(_TURN_SHARE * float(np.ptp(ref.values)), _TURN_STEPS * sensor.resolution,
                        _TURN_SIGMAS * sensor.noise_std)  # fmt: skip
        runs = {
            arm: simulate_tracking(
                plant,
                TrackingController(model, inverse=inv, integral_gain=integral_gain),
                ref.values,
                sensor=sensor,
                threshold=threshold,
            )  # fmt: skip
            for arm, inv in inverses.items()
        }
        out.append(Comparison(reference=ref, **runs))
    return out


def compensation_study(
    plant: BacklashModel,
    model: BacklashModel | None = None,
    *,
    band: float,
    integral_gain: float | None = None,
    sensor: Sensor = Sensor(),  # noqa: B008 - a frozen dataclass: one shared default is safe
    references: Sequence[Reference] | None = None,
    changes: Sequence[float] = CHANGES,
    families: Sequence[Family] = FAMILIES,
    progress: Callable[[int, int], None] | None = None,
) -> CompensationStudy:
    """Track the reference paths with and without the backlash inverse, nominal and perturbed.

    Parameters
    ----------
    plant : BacklashModel
        The simulated servo.
    model : BacklashModel, optional
        The controller's model (default: ``plant``, a perfect identification).
    band : float
        Smoothing band of the compensated arm, ``>= 0`` (output unit).
    integral_gain : float, optional
        ``k_i`` per sample (default
        :func:`~servoid.ident.control.tracking.default_integral_gain`).
    sensor : Sensor
        Encoder resolution and noise of the simulated measurement.
    references : sequence of Reference, optional
        Default :func:`~servoid.ident.control.references.reference_suite` of ``plant``.
    changes : sequence of float
        Relative perturbations of the model (``0.1`` is +10 %).
    families : sequence of {"dead zones", "all parameters"}
        What the perturbations scale.
    progress : callable, optional
        ``progress(done, total)`` after each model (nominal, then each perturbation).
    """
    model = plant if model is None else model
    band = validation.non_negative("band", band)
    refs = tuple(reference_suite(plant) if references is None else references)
    for fam in families:
        if fam not in FAMILIES:
            raise ModelError(f"family (={fam!r}) must be one of {', '.join(map(repr, FAMILIES))}")
    total = 1 + len(families) * len(changes)
    report = progress or (lambda done, total: None)
    comparisons = _arms(plant, model, refs, band=band, integral_gain=integral_gain, sensor=sensor)
    report(1, total)
    perturbations = []
    for fam in families:
        for change in changes:
            try:
                pmodel = perturbed(model, fam, change)
            except ModelError as exc:
                perturbations.append(Perturbation(fam, float(change), None, {}, note=f"invalid model: {exc}"))
                report(len(perturbations) + 1, total)
                continue
            try:
                runs = _arms(plant, pmodel, refs, band=band, integral_gain=integral_gain, sensor=sensor)
            except LoopDiverged as exc:
                perturbations.append(Perturbation(fam, float(change), pmodel, {}, note=str(exc)))
            else:
                summaries = {arm: ArmSummary.of([c.run(arm) for c in runs]) for arm in ARMS}
                perturbations.append(Perturbation(fam, float(change), pmodel, summaries))
            report(len(perturbations) + 1, total)
    controller = TrackingController(model, inverse=None, integral_gain=integral_gain)
    return CompensationStudy(
        plant=plant, model=model, band=band, integral_gain=controller.integral_gain, preview=controller.preview,
        sensor=sensor, comparisons=tuple(comparisons), perturbations=tuple(perturbations),
    )  # fmt: skip
