"""Propose a signal that visits every zone of the backlash inside a servo's limits.

From a rough prior (the play ``c1 + c2`` and the gain of the servo, or a
whole model) and the servo's limits (command range, largest step per sample,
sample period, the time it needs to follow a step), :func:`design` finds the
smallest amplitude whose signal, run through the prior, passes the
persistent-excitation report (Remark 2: as small as will do, yet reaching the
lines and the memory zone), adds a margin for the roughness of the prior, and
says how many samples to record.

For a servo whose encoder sits on the load (a Dynamixel's or Feetech's horn:
the play inside its position loop, ``Prior.structure``), the proposal is
gentle sines instead (:mod:`~servoid.excitation.gentle`): only a set point
that decelerates more gently than the load's own friction keeps the load on
the trailing flank, so that each reversal shows the whole play.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from servoid import validation
from servoid.errors import ConfigError, ModelError
from servoid.excitation.generate import sample
from servoid.excitation.gentle import segments
from servoid.excitation.report import ExcitationReport, Level, Verdict, assess, worst_level
from servoid.excitation.specs import GentleSpec, SignalSpec, StepsSpec, UniformSpec
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP, STRUCTURES

__all__ = ["Prior", "ServoLimits", "Design", "design"]

#: The amplitude found on the prior is multiplied by this, since the prior is rough.
MARGIN = 1.25

#: Amplitudes tried grow by this factor from the smallest that could reach the lines.
SEARCH_STEP = 1.1

#: Samples of the trial signals the search runs through the prior.
TRIAL_SAMPLES = 4000

#: Crossings of the play (line to line) a recording should contain; see
#: benchmarks/excitation_compare.py for how the error falls with them.
TARGET_LINE_SWITCHES = 600

#: Bounds of the proposed record length, samples.
MIN_SAMPLES = 3000
MAX_SAMPLES = 1_000_000

_BACKLASH = ("m2", "c1", "c2")

#: Gentle sines: amplitude as a multiple of the play (reversals far beyond the play), segments per record,
#: the share of the load's friction deceleration the set point may reach, and the frequency of a
#: full-amplitude segment when that deceleration is unknown (cycles per sample).
GENTLE_PLAYS = 25.0
GENTLE_SEGMENTS = 20
GENTLE_DECEL_SHARE = 0.4
GENTLE_DEFAULT_FREQUENCY = 0.01


@dataclass(frozen=True, kw_only=True)
class Prior:
    """What is roughly known about the servo before identification.

    Parameters
    ----------
    dead_zone : float
        The play ``c1 + c2``, unit of the measured position ``y``, ``> 0``.
    gain : float
        Steady-state gain from the command to ``x`` (unit of ``y`` per unit of
        ``u``), non-zero; 1 for a position servo commanded in its own unit.
    m2 : float
        Slope of the down line if known, ``> 0`` (default 1).
    model : BacklashModel, optional
        A whole prior model; when given it is used as is and the other fields
        are ignored.
    structure : str
        Where the play sits (:data:`~servoid.ident.models.structure_names.STRUCTURES`):
        ``play_in_loop`` for a servo whose encoder is on the load (the horn),
        which gets gentle sines.
    load_decel : float, optional
        The deceleration the load's own friction gives it, unit of ``y`` per
        s^2, if known: gentle sines stay below ``GENTLE_DECEL_SHARE`` of it.
    """

    dead_zone: float = 0.0
    gain: float = 1.0
    m2: float = 1.0
    model: BacklashModel | None = None
    structure: str = OUTPUT_BACKLASH
    load_decel: float | None = None

    def __post_init__(self) -> None:
        if self.structure not in STRUCTURES:
            raise ConfigError(f"structure (={self.structure!r}) must be one of {', '.join(STRUCTURES)}")
        if self.load_decel is not None:
            validation.positive("load_decel", self.load_decel)
        if self.model is not None:
            if not isinstance(self.model, BacklashModel):
                raise ConfigError(f"model must be a BacklashModel, got {type(self.model).__name__}")
            return
        validation.positive("dead_zone", self.dead_zone)
        if validation.real("gain", self.gain) == 0.0:
            raise ConfigError("gain (=0) must be non-zero: the command must move the servo")
        validation.positive("m2", self.m2)

    def as_model(self) -> BacklashModel:
        """The model the search runs signals through.

        Without a whole model: a static linear block ``x(k) = gain u(k-1)``
        (the dynamics are unknown) and the play split evenly, ``c1 = c2 =
        dead_zone / 2``.
        """
        if self.model is not None:
            return self.model
        try:
            return BacklashModel(
                a=(0.0,), b=(self.gain,), delay=1, m2=self.m2, c1=self.dead_zone / 2, c2=self.dead_zone / 2
            )
        except ModelError as exc:
            raise ConfigError(f"the prior is not a valid model: {exc}") from None

    @property
    def play(self) -> float:
        """``c1 + c2`` of the prior, unit of ``y``."""
        return self.as_model().dead_zone

    @property
    def dc_gain(self) -> float:
        """Steady-state gain of the prior's linear block."""
        return self.as_model().dc_gain


@dataclass(frozen=True, kw_only=True)
class ServoLimits:
    """What the servo allows.

    Parameters
    ----------
    position_min, position_max : float
        Range of the command ``u`` (a position setpoint, unit of ``u``).
    max_step : float
        Largest ``|u(k) - u(k-1)|``, unit of ``u`` per sample, ``> 0``; ``inf``
        when the servo takes any step.
    sample_period_s : float, optional
        Sample period in seconds, ``> 0``; needed with ``settle_s`` and for
        durations.
    settle_s : float, optional
        Time the servo needs to follow a step, seconds: each level is held at
        least this long.
    max_amplitude : float
        Largest amplitude around the centre the servo follows without
        saturating (a probe's finding,
        :func:`servoid.ident.online.probe_design.amplitude_cap`); ``inf``: the range's.
    """

    position_min: float
    position_max: float
    max_step: float = math.inf
    sample_period_s: float | None = None
    settle_s: float | None = None
    max_amplitude: float = math.inf

    def __post_init__(self) -> None:
        lo = validation.real("position_min", self.position_min)
        hi = validation.real("position_max", self.position_max)
        if not lo < hi:
            raise ConfigError(f"the position range [{lo:g}, {hi:g}] is empty: position_min must be < position_max")
        if not (isinstance(self.max_step, float) and self.max_step == math.inf):
            validation.positive("max_step", self.max_step)
        if self.sample_period_s is not None:
            validation.positive("sample_period_s", self.sample_period_s)
        if not (isinstance(self.max_amplitude, float) and self.max_amplitude == math.inf):
            validation.positive("max_amplitude", self.max_amplitude)
        if self.settle_s is not None:
            validation.non_negative("settle_s", self.settle_s)
            if self.sample_period_s is None:
                raise ConfigError("settle_s needs sample_period_s to be turned into samples")

    @property
    def centre(self) -> float:
        """Middle of the range: the operating point of the proposal."""
        return 0.5 * (self.position_min + self.position_max)

    @property
    def half_range(self) -> float:
        """Largest amplitude the range allows around its centre."""
        return 0.5 * (self.position_max - self.position_min)

    @property
    def settle_samples(self) -> int:
        """``settle_s`` in samples (at least 1)."""
        if self.settle_s is None or self.sample_period_s is None:
            return 1
        return max(1, math.ceil(self.settle_s / self.sample_period_s - 1e-9))


@dataclass(frozen=True)
class Design:
    """A proposed excitation.

    Attributes
    ----------
    spec : SignalSpec
        The signal.
    samples : int
        How many samples to record.
    duration_s : float or None
        ``samples`` times the sample period, when known.
    model : BacklashModel
        The prior model the proposal was checked on.
    report : ExcitationReport
        The report of the proposed signal through that model.
    verdicts : tuple of Verdict
        The report's verdicts that apply to the prior (with a rough prior,
        those about the guessed linear block are left out).
    reasons : tuple of str
        Why each choice was made, in words.
    """

    spec: SignalSpec
    samples: int
    duration_s: float | None
    model: BacklashModel
    report: ExcitationReport
    verdicts: tuple[Verdict, ...]
    reasons: tuple[str, ...]

    @property
    def level(self) -> Level:
        """The worst applicable verdict level."""
        return worst_level(self.verdicts)

    @property
    def sufficient(self) -> bool:
        """True when no applicable verdict is ``insufficient``."""
        return self.level != "insufficient"


def _spec_for(amplitude: float, limits: ServoLimits) -> SignalSpec:
    """The signal for one amplitude: white noise if the servo allows it, else held random steps."""
    swing = math.ceil(2.0 * amplitude / limits.max_step - 1e-9) if math.isfinite(limits.max_step) else 1
    hold = max(limits.settle_samples, swing, 1)
    if hold == 1 and not math.isfinite(limits.max_step):
        return UniformSpec(amplitude=amplitude, offset=limits.centre)
    return StepsSpec(amplitude=amplitude, offset=limits.centre, rate=limits.max_step, hold=hold)


def _applicable(report: ExcitationReport, *, rough: bool) -> tuple[Verdict, ...]:
    """The report's verdicts that apply to the prior.

    With a rough prior the linear block is a guess without dynamics, so what
    the report says about telling its ``a`` and ``b`` apart does not apply.
    """
    tm = report.through_model
    weakest_linear = tm is not None and tm.weakest not in _BACKLASH
    return tuple(v for v in report.verdicts if not (rough and v.topic == "information" and weakest_linear))


def _blocking(verdicts: tuple[Verdict, ...]) -> list[Verdict]:
    """Verdicts that make a trial signal not good enough (the range warning is cured by no larger amplitude)."""
    return [v for v in verdicts if v.level != "ok" and v.topic != "range"]


def _record_length(spec: SignalSpec, model: BacklashModel, seed: int, reasons: list[str]) -> int:
    """Samples for about ``TARGET_LINE_SWITCHES`` crossings of the play, from a trial run."""
    tm = assess(sample(spec, TRIAL_SAMPLES, seed=seed), model=model).through_model
    assert tm is not None
    per_sample = tm.line_switches / TRIAL_SAMPLES
    wanted = math.ceil(TARGET_LINE_SWITCHES / per_sample) if per_sample > 0 else MAX_SAMPLES
    samples = min(max(MIN_SAMPLES, 1000 * math.ceil(wanted / 1000)), MAX_SAMPLES)
    reasons.append(
        f"{samples} samples: about {TARGET_LINE_SWITCHES} crossings of the play at "
        f"{1000 * per_sample:.3g} per 1000 samples" + (" (capped)" if samples == MAX_SAMPLES else "")
    )
    return samples


def design(prior: Prior, limits: ServoLimits, *, seed: int = 0, samples: int | None = None) -> Design:
    """Propose a signal for ``prior`` inside ``limits``.

    Parameters
    ----------
    prior : Prior
        The rough prior (or a whole prior model).
    limits : ServoLimits
        The servo's limits.
    seed : int
        Seed of the trial signals (and of the proposal's report).
    samples : int, optional
        Record length to report on, instead of the proposed one.

    Returns
    -------
    Design

    Raises
    ------
    ConfigError
        When no amplitude inside the range passes the report, with the reason
        (the range is too narrow for the play, or the rate limit too tight).

    Notes
    -----
    The search starts at the amplitude that just moves ``x`` across the play
    (``(c1 + c2) / (2 |gain|)``) and grows it by ``SEARCH_STEP`` until the
    signal's report through the prior has no insufficient verdict and no
    warning but the range one; the proposal is that amplitude times
    ``MARGIN``, capped by the range. The hold time follows from the limits:
    long enough for the servo to settle (``settle_s``) and for a full swing
    at the rate limit (``2 amplitude / max_step``). With neither, the signal is
    the paper's uniform white noise.
    """
    if prior.structure == PLAY_IN_LOOP:
        return _design_gentle(prior, limits, seed=seed, samples=samples)
    model = prior.as_model()
    gain = abs(model.dc_gain)
    play = model.dead_zone
    half = min(limits.half_range, limits.max_amplitude)
    reach = play / (2.0 * gain)
    if reach >= half:
        raise ConfigError(
            f"the position range [{limits.position_min:g}, {limits.position_max:g}]"
            f"{' allows' if half == limits.half_range else ' and the saturation the probe found allow'} an amplitude of "
            f"{half:.4g}, but the play c1 + c2 = {play:.4g} needs more than {reach:.4g} (play / (2 |gain|), "
            f"gain {gain:.4g}) before the output moves at all: widen the range or check the prior"
        )
    rough = prior.model is None
    amplitude = reach
    found: float | None = None
    blocking: list[Verdict] = []
    while amplitude < half:
        amplitude = min(amplitude * SEARCH_STEP, half)
        trial = _spec_for(amplitude, limits)
        trial_report = assess(sample(trial, TRIAL_SAMPLES, seed=seed), model=model)
        blocking = _blocking(_applicable(trial_report, rough=rough))
        if not blocking:
            found = amplitude
            break
    reasons: list[str] = []
    if rough:
        reasons.append(
            f"prior: x(k) = {model.b[0]:.4g} u(k-1) (no dynamics known), c1 = c2 = {model.c1:.4g}, m2 = {model.m2:.4g}; "
            "what the report says about the linear block (a, b) only holds for that guess"
        )
    if found is None:
        insufficient = [v for v in blocking if v.level == "insufficient"]
        if insufficient:
            why = "; ".join(v.message for v in insufficient)
            raise ConfigError(
                f"no signal inside the position range [{limits.position_min:g}, {limits.position_max:g}] "
                f"(max step {limits.max_step:g} per sample) excites the prior enough: at the largest amplitude "
                f"{half:.4g}: {why}"
            )
        chosen = half
        reasons.append(f"amplitude {chosen:.4g}: the whole range, and still with warnings (see the report)")
    else:
        chosen = min(found * MARGIN, half)
        reasons.append(
            f"amplitude {chosen:.4g}: the smallest that passes the report on the prior ({found:.4g}, Remark 2: "
            f"as small as will do) x {MARGIN}, a margin for an uncertain prior"
            + (
                (", capped by the range" if half == limits.half_range else ", capped where the drive saturates")
                if chosen == half
                else ""
            )
        )
    spec = _spec_for(chosen, limits)
    reasons.append(
        f"offset {limits.centre:.4g}: the middle of the range [{limits.position_min:g}, {limits.position_max:g}]"
    )
    if isinstance(spec, StepsSpec):
        why_hold = []
        if limits.settle_samples > 1:
            why_hold.append(f"the servo settles in {limits.settle_samples} samples")
        if math.isfinite(limits.max_step):
            why_hold.append(
                f"a full swing takes {math.ceil(2 * chosen / limits.max_step - 1e-9)} samples at the max step"
            )
        reasons.append(f"random steps held {spec.hold} samples: {' and '.join(why_hold)}")
    else:
        reasons.append("uniform white noise (the paper's input): the servo takes any step every sample")
    if samples is None:
        samples = _record_length(spec, model, seed, reasons)
    else:
        samples = validation.integer("samples", samples, minimum=1)
        reasons.append(f"{samples} samples, as asked")
    report = assess(sample(spec, samples, seed=seed), model=model)
    duration = None if limits.sample_period_s is None else samples * limits.sample_period_s
    return Design(
        spec=spec, samples=samples, duration_s=duration, model=model, report=report,
        verdicts=_applicable(report, rough=rough), reasons=tuple(reasons),
    )  # fmt: skip


def _design_gentle(prior: Prior, limits: ServoLimits, *, seed: int, samples: int | None) -> Design:
    """Gentle sines for a servo whose loop is closed around the play (see the module docstring)."""
    model = prior.as_model()
    play = model.dead_zone
    half = limits.half_range
    if 2.0 * play >= half:
        raise ConfigError(
            f"the position range [{limits.position_min:g}, {limits.position_max:g}] allows an amplitude of "
            f"{half:.4g}: too small to reverse by more than twice the play {play:.4g}; widen the range"
        )
    amplitude = min(GENTLE_PLAYS * play, half)
    reasons = [
        "gentle sines: the servo's encoder sits on the load, so its loop is closed around the play; only a "
        "set point that decelerates more gently than the load's friction keeps the load on the trailing flank, "
        "so that every reversal shows the whole play (held steps or white noise let it coast across: "
        "the play vanishes from the record)",
        f"amplitude {amplitude:.4g}: {GENTLE_PLAYS:g} plays, so that reversals go far beyond the play"
        + (", capped by the range" if amplitude == half else ""),
        f"offset {limits.centre:.4g}: the middle of the range [{limits.position_min:g}, {limits.position_max:g}]",
    ]
    period = limits.sample_period_s
    if prior.load_decel is not None and period is not None:
        accel = GENTLE_DECEL_SHARE * prior.load_decel * period * period
        reasons.append(
            f"peak acceleration at most {GENTLE_DECEL_SHARE:g} x the load's friction deceleration "
            f"{prior.load_decel:.4g}/s^2 ({accel:.4g} per sample^2)"
        )
    else:
        accel = amplitude * (2.0 * math.pi * GENTLE_DEFAULT_FREQUENCY) ** 2
        reasons.append(
            f"peak acceleration at most {accel:.4g} per sample^2 (a full-amplitude segment at "
            f"{GENTLE_DEFAULT_FREQUENCY:g} cycles per sample): the load's friction is not known "
            "(give it to design for the gentlest fast signal)"
        )
    spec = GentleSpec(amplitude=amplitude, offset=limits.centre, rate=limits.max_step, accel=accel)
    if math.isfinite(limits.max_step):
        reasons.append(f"rate limit {limits.max_step:g} per sample: the servo's largest step")
    if samples is None:
        lengths = segments(spec, seed, 0, GENTLE_SEGMENTS)[2]
        samples = int(min(max(MIN_SAMPLES, int(lengths.sum())), MAX_SAMPLES))
        reasons.append(
            f"{samples} samples: {GENTLE_SEGMENTS} segments of {spec.cycles} periods, {2 * spec.cycles} reversals each"
        )
    else:
        samples = validation.integer("samples", samples, minimum=1)
        reasons.append(f"{samples} samples, as asked")
    reasons.append(
        "sample at least 20 times the position loop's bandwidth: the play's dead time at a reversal must span a sample"
    )
    report = assess(sample(spec, samples, seed=seed), model=model)
    duration = None if period is None else samples * period
    return Design(
        spec=spec, samples=samples, duration_s=duration, model=model, report=report,
        verdicts=_applicable(report, rough=prior.model is None), reasons=tuple(reasons),
    )  # fmt: skip
