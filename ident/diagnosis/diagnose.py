"""The discrepancy workflow: where model and measurement disagree, which effect is missing, what it is worth.

:func:`diagnose` takes a training and a validation record:

1. identifies the base model on the training record (:func:`servoid.ident.identify`:
   MRGIA, then output-error refinement);
2. simulates it on the validation input (free run) and breaks the residual
   down by regime (:mod:`servoid.ident.diagnosis.residuals`);
3. fits every candidate effect of :mod:`servoid.ident.models.effects` jointly with
   all base parameters on the training record (:func:`~servoid.ident.models.extended.fit_extended`,
   a few starts per effect, the best *training* fit kept), and scores each on
   the validation record;
4. accepts the best candidate only if it pays (see *Selection* below), and
   repeats from the extended model for a further effect, up to
   ``max_effects``;
5. when the sample period is known and the final model's validation residual
   is coloured, fits the servo-loop model with and without its friction terms and names ``friction_stall`` when they pay
   (:mod:`servoid.ident.diagnosis.loop_effects`): a drive that stalls after
   each reversal is an effect inside the loop, which the black box books as play; on the same
   model's validation run it names ``flank_rebound`` when the load bounces off the flank after
   reversals (:mod:`servoid.ident.diagnosis.flank_rebound`: the massless play is then biased).

Selection
---------
The gap of a model is its free-run NRMSE ``rms(y - y_hat) / std(y)`` on the
validation record, which the fits never saw. A candidate with ``k`` extra
parameters scores ``gap * (1 + penalty)^k``; the model without it scores its
own gap (``k = 0``). The lowest score wins, so a candidate must cut the
validation gap by more than ``penalty`` (default 10 %) per parameter to be
accepted, and ``"none"`` is the answer when no candidate does. A purely
validation-based AIC (``N ln(gap^2) + 2k``) would accept improvements of a
few hundredths of a percent on 6000 samples; free-run residuals are strongly
correlated, so the effective number of independent samples is far smaller
than ``N`` and such improvements are noise. The relative threshold is simple,
unit-free and was calibrated on the hidden-effect benchmark
(``benchmarks/diagnose_hidden_effects.py``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, DataError, ModelError
from servoid.ident.defaults import DEFAULT_PENALTY, MAX_EFFECTS, REVERSAL_WINDOW
from servoid.ident.diagnosis.loop_effects import FRICTION_TERMS, LoopEffect, loop_effects
from servoid.ident.diagnosis.residuals import (
    RegimeBreakdown,
    ResidualTests,
    regime_breakdown,
    residual_tests,
    where_text,
)
from servoid.ident.identify import Identification, check_record, identify
from servoid.ident.metrics import nrmse
from servoid.ident.models.effect_names import FLANK_REBOUND, FRICTION_STALL
from servoid.ident.models.effects import CANDIDATE_NAMES, EFFECTS, NONE, get_effect
from servoid.ident.models.extended import (
    AppliedEffect,
    ExtendedModel,
    ExtendedSimulation,
    fit_extended,
    simulate_extended,
)
from servoid.ident.online.mrgia import MRGIAConfig

__all__ = ["DiagnoseConfig", "Candidate", "Round", "Diagnosis", "diagnose", "select"]


@dataclass(frozen=True, kw_only=True)
class DiagnoseConfig:
    """Settings of :func:`diagnose`.

    Parameters
    ----------
    identification : MRGIAConfig
        Orders, delay and estimator settings of the base model.
    candidates : tuple of str
        Effects to try (default: the whole library).
    penalty : float
        Relative cut of the validation gap each extra parameter must buy (> 0).
    max_effects : int
        Most effects added one after the other (>= 1).
    reversal_window : int
        Samples after a reversal counted as "just after" in the regime breakdown.
    max_nfev : int or None
        Cap on simulations per candidate fit (default: scipy's).
    """

    identification: MRGIAConfig
    candidates: tuple[str, ...] = CANDIDATE_NAMES
    penalty: float = DEFAULT_PENALTY
    max_effects: int = MAX_EFFECTS
    reversal_window: int = REVERSAL_WINDOW
    max_nfev: int | None = None

    def __post_init__(self) -> None:
        names = tuple(self.candidates)
        for name in names:
            get_effect(name)
        if not names:
            raise ConfigError("candidates is empty: name at least one effect to try")
        object.__setattr__(self, "candidates", names)
        validation.positive("penalty", self.penalty)
        validation.integer("max_effects", self.max_effects, minimum=1)
        validation.integer("reversal_window", self.reversal_window, minimum=1)
        if self.max_nfev is not None:
            validation.integer("max_nfev", self.max_nfev, minimum=1)


@dataclass(frozen=True)
class Candidate:
    """One candidate of a round: the model with the effect added, fitted and scored.

    Attributes
    ----------
    effect : str
        Its name (``"none"`` for the model of the round without a new effect).
    model : ExtendedModel
        The fitted model.
    extra_parameters : int
        Parameters it adds to the round's starting model.
    train_nrmse : float
        Free-run NRMSE on the training record.
    gap : float
        Free-run NRMSE on the validation record.
    score : float
        ``gap * (1 + penalty)^extra_parameters``; lowest wins.
    stderr : dict
        Standard errors of the fitted parameters (empty for ``"none"``).
    """

    effect: str
    model: ExtendedModel
    extra_parameters: int
    train_nrmse: float
    gap: float
    score: float
    stderr: dict[str, float]

    @property
    def parameters(self) -> dict[str, float]:
        """The new effect's parameters (empty for ``"none"``)."""
        applied = self.model.effect(self.effect)
        return {} if applied is None else applied.parameters

    def to_dict(self) -> dict[str, Any]:
        """``{"effect", "gap", "score", "train_nrmse", "extra_parameters", "parameters"}``."""
        return {"effect": self.effect, "gap": self.gap, "score": self.score, "train_nrmse": self.train_nrmse,
                "extra_parameters": self.extra_parameters, "parameters": self.parameters}  # fmt: skip


@dataclass(frozen=True)
class Round:
    """One round of the workflow: every candidate tried on top of ``start``.

    Attributes
    ----------
    start : ExtendedModel
        The model the round started from.
    candidates : tuple of Candidate
        ``"none"`` first, then each effect tried, in library order.
    chosen : Candidate
        The lowest score (``"none"`` when nothing pays).
    """

    start: ExtendedModel
    candidates: tuple[Candidate, ...]
    chosen: Candidate

    def to_dict(self) -> dict[str, Any]:
        """``{"chosen": effect, "candidates": [...]}``."""
        return {"chosen": self.chosen.effect, "candidates": [c.to_dict() for c in self.candidates]}


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`.

    Attributes
    ----------
    identification : Identification
        The base identification on the training record.
    base, model : ExtendedModel
        The base model and the final model (base plus the accepted effects).
    rounds : tuple of Round
        Each round of candidates; the last one chose ``"none"`` unless ``max_effects`` stopped it.
    gap_before, gap_after : float
        Validation NRMSE of the base and of the final model.
    where : str
        Where the base model's error concentrates, in words.
    breakdown_before, breakdown_after : RegimeBreakdown
        The validation residual by regime, base and final model.
    resid_before, resid_after : ResidualTests
        Residual whiteness and independence from past inputs, base and final model.
    validation_before, validation_after : ExtendedSimulation
        Free runs on the validation input (for plots).
    config : DiagnoseConfig
        The settings used.
    loop : LoopEffect or None
        The servo-loop model with and without friction (None when it was not looked for: no sample
        period, a white validation residual, or a record too short).
    """

    identification: Identification
    base: ExtendedModel
    model: ExtendedModel
    rounds: tuple[Round, ...]
    gap_before: float
    gap_after: float
    where: str
    breakdown_before: RegimeBreakdown
    breakdown_after: RegimeBreakdown
    resid_before: ResidualTests
    resid_after: ResidualTests
    validation_before: ExtendedSimulation
    validation_after: ExtendedSimulation
    config: DiagnoseConfig
    loop: LoopEffect | None = None

    def __repr__(self) -> str:
        return (
            f"Diagnosis(missing: {', '.join(self.effects) or NONE}; validation gap {self.gap_before:.4g} -> "
            f"{self.gap_after:.4g})"
        )

    @property
    def effects(self) -> tuple[str, ...]:
        """Names of the missing effects (empty when nothing is missing).

        The black box's accepted effects in the order found, and ``friction_stall`` when the
        servo-loop model names it: first when the loop model with friction validates better
        than the black box with its effects (the stall is then what they were standing in for);
        ``flank_rebound`` last when the servo-loop model's residual names it (no model here
        follows the bounce, so it closes no gap).
        """
        found = self.model.effect_names
        if self.loop is None:
            return found
        if self.loop.named:
            found = (FRICTION_STALL, *found) if self.loop.gap_with < self.gap_after else (*found, FRICTION_STALL)
        return (*found, FLANK_REBOUND) if self.loop.rebounds else found

    @property
    def effect(self) -> str:
        """The first (most important) missing effect, or ``"none"``."""
        return self.effects[0] if self.effects else NONE

    @property
    def effect_parameters(self) -> dict[str, float]:
        """Parameters of :attr:`effect` in the final model (empty for ``"none"``; the servo loop's friction
        and stall band for ``friction_stall``; the residual's swing, a share of the play, its t statistics
        and the departures for ``flank_rebound``)."""
        if self.effect == FRICTION_STALL and self.loop is not None:
            params = self.loop.model.params()
            return {**{name: params[name] for name in FRICTION_TERMS}, "stall_band": self.loop.stall_band}
        if self.effect == FLANK_REBOUND and self.loop is not None and self.loop.rebound is not None:
            b = self.loop.rebound
            return {"swing": b.swing, "lead_t": b.lead_t, "lag_t": b.lag_t, "departures": float(b.departures)}
        applied = self.model.effect(self.effect)
        return {} if applied is None else applied.parameters

    @property
    def candidates(self) -> tuple[Candidate, ...]:
        """The first round's candidates: every effect tried on the base model."""
        return self.rounds[0].candidates

    def to_dict(self) -> dict[str, Any]:
        """For JSON. The fixed keys come first: ``effect``, ``effect_parameters``, ``where``,
        ``gap_before``, ``gap_after`` (validation NRMSEs) and ``candidates`` (the first round: every
        effect tried on the base model); then ``effects``, ``rounds``, ``model``, ``base_model``,
        ``parameter_units``, ``penalty``, the regimes and residual tests before and after, ``warnings``.
        """
        return {
            "effect": self.effect,
            "effect_parameters": self.effect_parameters,
            "where": self.where,
            "gap_before": self.gap_before,
            "gap_after": self.gap_after,
            "candidates": [c.to_dict() for c in self.candidates],
            "effects": self.model.effects_json(),
            "rounds": [r.to_dict() for r in self.rounds],
            "model": self.model.to_dict(),
            "base_model": self.base.base.to_dict(),
            "parameter_units": {name: dict(zip(e.parameters, e.units)) for name, e in EFFECTS.items()},
            "penalty": self.config.penalty,
            "regimes_before": self.breakdown_before.to_dict()["regimes"],
            "regimes_after": self.breakdown_after.to_dict()["regimes"],
            "residual_tests_before": self.resid_before.to_dict(),
            "residual_tests_after": self.resid_after.to_dict(),
            "warnings": list(self.identification.warnings),
            "loop_effect": None if self.loop is None else self.loop.to_dict(),
        }


def _score(gap: float, extra: int, penalty: float) -> float:
    return gap * (1.0 + penalty) ** extra


def select(candidates: Sequence[Candidate]) -> Candidate:
    """The candidate with the lowest score (ties go to the earlier one, ``"none"`` first)."""
    return min(candidates, key=lambda c: c.score)


class _Records:
    """Training and validation records with their free-run helpers."""

    def __init__(self, train: tuple[np.ndarray, np.ndarray], val: tuple[np.ndarray, np.ndarray]) -> None:
        self.u_t, self.y_t = train
        self.u_v, self.y_v = val

    def train_nrmse(self, model: ExtendedModel) -> float:
        return nrmse(self.y_t, simulate_extended(model, self.u_t, y0=float(self.y_t[0])).y)

    def error_in_input_units(self, model: ExtendedModel) -> float:
        """RMS training free-run error of ``model`` divided by its static gain: the error's size seen from ``u``."""
        y_hat = simulate_extended(model, self.u_t, y0=float(self.y_t[0])).y
        gain = abs(model.base.dc_gain)
        rms = float(np.sqrt(np.mean((self.y_t - y_hat) ** 2)))
        return rms / gain if gain > 0 else rms

    def validation(self, model: ExtendedModel) -> ExtendedSimulation:
        return simulate_extended(model, self.u_v, y0=float(self.y_v[0]))

    def gap(self, model: ExtendedModel) -> float:
        return nrmse(self.y_v, self.validation(model).y)


def _fit_best(
    records: _Records, starts: Sequence[ExtendedModel], max_nfev: int | None
) -> tuple[ExtendedModel, dict[str, float]] | None:
    """Fit from each start on the training record; keep the best training fit."""
    best = None
    for start in starts:
        try:
            fit = fit_extended(records.u_t, records.y_t, start, max_nfev=max_nfev)
        except ModelError:
            continue
        if best is None or fit.nrmse < best.nrmse:
            best = fit
    if best is None:
        return None
    return best.model, best.stderr_dict()


def _delay_starts(
    records: _Records, current: ExtendedModel, extra: int, ident_config: MRGIAConfig
) -> list[ExtendedModel]:
    """Starts for ``extra_delay = extra``: the current model as it is, and a base re-identified with the longer delay.

    With the wrong delay the base coefficients are fitted to the wrong lag,
    a poor start; the MRGIA run with the longer delay gives a good one.
    """
    effect = AppliedEffect(EFFECTS["extra_delay"].name, (float(extra),))
    starts = [current.with_effect(effect)]
    cfg = dataclasses.replace(ident_config, delay=ident_config.delay + extra)
    try:
        longer = identify(records.u_t, records.y_t, cfg, servo_loop=False).model
    except (ModelError, DataError, ArithmeticError):
        return starts
    base = dataclasses.replace(longer, delay=current.base.delay)
    starts.append(ExtendedModel(base, current.effects).with_effect(effect))
    return starts


def _pole_starts(records: _Records, current: ExtendedModel, ident_config: MRGIAConfig) -> list[ExtendedModel]:
    """Extra starts for ``extra_pole``: a base identified with ``na + 1``, one real pole split off.

    When the missing pole is slow, the base model of order ``na`` is a poor
    start (its free run may even stay inside the backlash's memory zone, where
    the gradient vanishes); the MRGIA of order ``na + 1`` finds the poles,
    and each real one is tried as the extra pole.
    """
    cfg = dataclasses.replace(ident_config, na=ident_config.na + 1, theta0=None)
    try:
        wider = identify(records.u_t, records.y_t, cfg, servo_loop=False).model
    except (ModelError, DataError, ArithmeticError):
        return []
    starts = []
    poles = np.asarray(wider.poles)
    for i, pole in enumerate(poles):
        if abs(pole.imag) > 1e-9 or abs(pole.real) >= 1.0:
            continue
        p = float(pole.real)
        rest = np.real(np.poly(np.delete(poles, i)))[1:]
        try:
            base = dataclasses.replace(current.base, a=tuple(rest.tolist()), b=tuple((np.asarray(wider.b) / (1.0 - p)).tolist()),
                                       m2=wider.m2, c1=wider.c1, c2=wider.c2)  # fmt: skip
        except ModelError:
            continue
        starts.append(ExtendedModel(base, current.effects).with_effect(AppliedEffect(EFFECTS["extra_pole"].name, (p,))))
    return starts


def _candidate(records: _Records, current: ExtendedModel, name: str, config: DiagnoseConfig) -> Candidate | None:
    effect = get_effect(name)
    best: tuple[ExtendedModel, dict[str, float]] | None = None
    if effect.integer:
        fits = []
        for extra in effect.choices:
            fitted = _fit_best(records, _delay_starts(records, current, extra, config.identification), config.max_nfev)
            if fitted is not None:
                fits.append((records.train_nrmse(fitted[0]), fitted))
        if fits:
            best = min(fits, key=lambda f: f[0])[1]
    else:
        error_u = records.error_in_input_units(current)
        starts = [
            current.with_effect(AppliedEffect(name, tuple(v.tolist()))) for v in effect.starts(records.u_t, error_u)
        ]
        if name == EFFECTS["extra_pole"].name:
            starts += _pole_starts(records, current, config.identification)
        best = _fit_best(records, starts, config.max_nfev)
    if best is None:
        return None
    model, stderr = best
    gap = records.gap(model)
    return Candidate(
        effect=name, model=model, extra_parameters=effect.n_params, train_nrmse=records.train_nrmse(model),
        gap=gap, score=_score(gap, effect.n_params, config.penalty), stderr=stderr,
    )  # fmt: skip


def _round(
    records: _Records, current: ExtendedModel, config: DiagnoseConfig, progress: Callable[[str], None] | None
) -> Round:
    gap = records.gap(current)
    none = Candidate(effect=NONE, model=current, extra_parameters=0, train_nrmse=records.train_nrmse(current),
                     gap=gap, score=gap, stderr={})  # fmt: skip
    candidates = [none]
    for name in config.candidates:
        if name in current.effect_names:
            continue
        if progress is not None:
            progress(name)
        cand = _candidate(records, current, name, config)
        if cand is not None:
            candidates.append(cand)
    return Round(start=current, candidates=tuple(candidates), chosen=select(candidates))


def _check_pair(
    train: tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray],
    val: tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray],
    config: MRGIAConfig,
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    try:
        t = check_record(*train, config)
    except DataError as exc:
        raise DataError(f"training record: {exc}") from None
    try:
        v = check_record(*val, config)
    except DataError as exc:
        raise DataError(f"validation record: {exc}") from None
    return t, v


def diagnose(
    train_u: Sequence[float] | np.ndarray,
    train_y: Sequence[float] | np.ndarray,
    validate_u: Sequence[float] | np.ndarray,
    validate_y: Sequence[float] | np.ndarray,
    config: DiagnoseConfig,
    *,
    progress: Callable[[str], None] | None = None,
    sample_period_s: float | None = None,
) -> Diagnosis:
    """Find where the identified model and the measurement disagree and which effect is missing.

    Parameters
    ----------
    train_u, train_y : array_like
        The training record (identification and every fit).
    validate_u, validate_y : array_like
        The validation record (scores only; never fitted).
    config : DiagnoseConfig
        Orders, delay, candidates and the selection penalty.
    progress : callable, optional
        Called with each candidate's name before it is fitted.
    sample_period_s : float, optional
        The records' sample period, s: the servo-loop model needs it to look for
        ``friction_stall`` (:func:`~servoid.ident.diagnosis.loop_effects.loop_effects`);
        without it, or when the black box with its effects leaves a white validation
        residual (nothing for the loop model to explain), that effect is not looked for.

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        A record that cannot be identified (named: training or validation).
    ModelError
        When the model, with the effects found, still fits the validation
        record worse than predicting its mean: an error, not "none".
    """
    train, val = _check_pair((train_u, train_y), (validate_u, validate_y), config.identification)
    # diagnose extends the black box by effects: the servo-loop model is not its base
    ident = identify(*train, config.identification, servo_loop=False)
    op = ident.operating_point
    if not op.is_zero:  # the model exists only about the record's operating point: diagnose there
        train, val = op.centre(*train), op.centre(*val)
    records = _Records(train, val)
    base = ExtendedModel(ident.model)
    rounds: list[Round] = []
    current = base
    for _ in range(config.max_effects):
        rnd = _round(records, current, config, progress)
        rounds.append(rnd)
        if rnd.chosen.effect == NONE:
            break
        current = rnd.chosen.model
        if len(current.effects) == len(config.candidates):
            break

    final_fit = records.gap(current)
    if not final_fit < 1.0:
        # "none" (or any effect) on a model no better than the mean would be a confident wrong answer
        raise ModelError(
            f"the model fits the validation record worse than predicting its mean (free-run NRMSE "
            f"{final_fit:.3g} >= 1, base model {records.gap(base):.3g}) even with the effects tried: there is "
            "nothing to name a missing effect against; check the records, the orders and the delay"
        )
    before = records.validation(base)
    after = records.validation(current)
    resid_after = residual_tests(records.y_v - after.y, records.u_v)
    loop: LoopEffect | None = None
    # identify's skip rule: a black box whose residual is white leaves the servo-loop model nothing to explain
    if sample_period_s is not None and not resid_after.white:
        period = validation.positive("sample_period_s", sample_period_s)
        try:
            loop = loop_effects(train, val, period)
        except ConfigError:  # too short for the servo-loop model: the effect is not looked for
            loop = None
    motion = before.x
    window, lag = config.reversal_window, config.identification.delay
    breakdown_before = regime_breakdown(
        records.y_v, before.y, records.u_v, motion, reversal_window=window, input_lag=lag
    )
    breakdown_after = regime_breakdown(records.y_v, after.y, records.u_v, motion, reversal_window=window, input_lag=lag)
    return Diagnosis(
        identification=ident,
        base=base,
        model=current,
        rounds=tuple(rounds),
        gap_before=breakdown_before.nrmse,
        gap_after=breakdown_after.nrmse,
        where=where_text(breakdown_before),
        breakdown_before=breakdown_before,
        breakdown_after=breakdown_after,
        resid_before=residual_tests(records.y_v - before.y, records.u_v),
        resid_after=resid_after,
        validation_before=before,
        validation_after=after,
        config=config,
        loop=loop,
    )
