"""Will this input do? The persistent-excitation report, before a sample is sent.

Two views of one input ``u``:

the signal alone (:class:`InputStats`)
    Range, crest factor, largest step, direction reversals, and the order of
    persistent excitation: the largest ``m`` for which the ``m x m`` covariance
    (Toeplitz) matrix of the input is well conditioned.
the signal run through a model (:class:`ModelExcitation`)
    A prior guess or an identified model is simulated noise-free on ``u``:
    the share of samples on the up line, the down line and in the memory
    zone, how often the output crosses the play from one line to the other,
    and the information matrix ``(1/n) sum Phi h h^T`` of the MRGIA's
    regressor (eq. 25, :mod:`servoid.excitation.regressor`): its smallest and
    largest eigenvalues are the ``gamma`` and ``beta`` of Lemma 1, and their
    ratio its condition number.

:func:`assess` computes both and turns them into plain verdicts with reasons
(:class:`Verdict`). The thresholds are module constants, chosen on the
paper's plant (see ``benchmarks/excitation_compare.py``) and documented in
``docs/excitation.md``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.excitation.regressor import regressor
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import Simulation, simulate
from servoid.ident.serialise import number

__all__ = [
    "Verdict",
    "InputStats",
    "ModelExcitation",
    "ExcitationReport",
    "assess",
    "input_stats",
    "through_model",
    "worst_level",
]

Level = Literal["ok", "warning", "insufficient"]

#: Largest condition number of the input covariance matrix counted as full rank
#: (the order of persistent excitation is the largest order below it).
PE_CONDITION_LIMIT = 1e6

#: Above this condition number at the needed order the input is poorly conditioned.
PE_CONDITION_WARN = 1e3

#: Orders of persistent excitation tested by default, at least.
DEFAULT_MAX_ORDER = 10

#: Below this ratio of its extreme eigenvalues a matrix counts as singular.
SINGULAR_RATIO = 1e-10

#: Collinearity (condition number of the information matrix scaled to unit
#: diagonal) above which the parameters are poorly separated: a warning ...
COLLINEARITY_WARN = 250.0

#: ... and above which the input is insufficient when the least separated
#: parameter is one of the backlash (m2, c1, c2). On the paper's plant at SNR 43,
#: uniform inputs of amplitude 1.0 (collinearity ~170) identify well, 0.8 (~350)
#: fails in half the seeds and 0.6 (~1800) in nearly all.
COLLINEARITY_LIMIT = 1000.0

#: Fewer crossings of the play than this (up line to down line or back) leave c1, c2 poorly seen.
MIN_LINE_SWITCHES = 50

#: Above this share of samples in the memory zone the online MRGIA tends to
#: stall (it learns only on the lines): a warning.
MEMORY_SHARE_WARN = 0.85


@dataclass(frozen=True)
class Verdict:
    """One finding of the report.

    Attributes
    ----------
    level : {"ok", "warning", "insufficient"}
        ``insufficient``: this input will not identify the model; ``warning``:
        it may, slowly or poorly; ``ok``: a check passed.
    topic : str
        What was checked (``"excitation order"``, ``"zones"``, ...).
    message : str
        The finding and, when it is not ok, what to change.
    """

    level: Level
    topic: str
    message: str

    def to_dict(self) -> dict[str, str]:
        """``{"level", "topic", "message"}``."""
        return {"level": self.level, "topic": self.topic, "message": self.message}


@dataclass(frozen=True)
class InputStats:
    """The input on its own.

    Attributes
    ----------
    samples : int
        Length.
    minimum, maximum, mean, std : float
        Range and moments, unit of ``u``.
    crest_factor : float
        ``max |u - mean| / std`` (``inf`` for a constant).
    max_step : float
        Largest ``|u(k) - u(k-1)|``, unit of ``u`` per sample.
    reversals : int
        Changes of direction of ``u`` (constant stretches skipped).
    pe_order : int
        Order of persistent excitation: the largest ``m <= pe_max_order`` whose
        ``m x m`` covariance matrix of ``u - mean(u)`` has a condition number
        ``<= PE_CONDITION_LIMIT``; 0 for a constant input.
    pe_max_order : int
        Largest order tested (an order equal to it means "at least").
    pe_condition : tuple of float
        Condition number of the covariance matrix for ``m = 1 .. pe_max_order``.
    """

    samples: int
    minimum: float
    maximum: float
    mean: float
    std: float
    crest_factor: float
    max_step: float
    reversals: int
    pe_order: int
    pe_max_order: int
    pe_condition: tuple[float, ...]


@dataclass(frozen=True)
class ModelExcitation:
    """The input run through a model (noise-free).

    Attributes
    ----------
    model : BacklashModel
        The model (a prior guess or an identified one).
    share_up, share_down, share_memory : float
        Shares of samples on the up line, the down line and in the memory zone.
    reversals : int
        Changes of direction of ``x``, the input of the backlash.
    line_switches : int
        Crossings of the play: changes from the up line to the down line or
        back (memory-zone samples in between skipped). Each one shows the
        estimator both dead zones.
    update_share : float
        Share of samples with ``Phi = 1`` (eq. 42), on which the MRGIA updates.
    gamma, beta : float
        Smallest and largest eigenvalue of the information matrix
        ``(1/n) sum Phi(k) h(k) h(k)^T`` (Lemma 1, in its matrix reading:
        ``gamma I <= ... <= beta I``).
    trace : float
        ``(1/n) sum Phi(k) h(k)^T h(k)``, Lemma 1's scalar as printed.
    condition : float
        ``beta / gamma`` (``inf`` when ``gamma <= 0``); depends on the units
        of the parameters.
    collinearity : float
        Condition number of the information matrix scaled to unit diagonal:
        free of units, 1 when every parameter is seen independently of the
        others, ``inf`` when one is not seen at all.
    weakest : str
        The parameter with the largest variance inflation factor (the
        diagonal of the inverse of the scaled matrix): the one the input
        tells least apart from the others.
    x_span : float
        Range of ``x`` that holds 99% of the samples (from the 0.5th to the
        99.5th percentile, so that a start-up transient does not count), unit
        of ``y``, to compare with the play ``c1 + c2``.
    beyond_crossing : int
        Samples with ``x`` beyond the point where the up and down lines cross,
        where the paper's model is ambiguous.
    simulation : Simulation
        The run these numbers come from (``x``, ``y_clean``, per-sample ``zone``).
    """

    model: BacklashModel
    share_up: float
    share_down: float
    share_memory: float
    reversals: int
    line_switches: int
    update_share: float
    gamma: float
    beta: float
    trace: float
    condition: float
    collinearity: float
    weakest: str
    x_span: float
    beyond_crossing: int
    simulation: Simulation = field(repr=False, compare=False)


@dataclass(frozen=True)
class ExcitationReport:
    """What :func:`assess` found.

    Attributes
    ----------
    signal : InputStats
        The input on its own.
    through_model : ModelExcitation or None
        The input run through a model, when one was given.
    needed_order : int or None
        The order of persistent excitation the linear block needs
        (``na + nb + 1`` of the model), when known.
    verdicts : tuple of Verdict
        Findings, the worst first.
    """

    signal: InputStats
    through_model: ModelExcitation | None
    needed_order: int | None
    verdicts: tuple[Verdict, ...]

    @property
    def sufficient(self) -> bool:
        """True when no verdict is ``insufficient``."""
        return worst_level(self.verdicts) != "insufficient"

    @property
    def level(self) -> Level:
        """The worst verdict level."""
        return worst_level(self.verdicts)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (no per-sample arrays)."""
        sig = self.signal
        out: dict[str, Any] = {
            "verdict": self.level,
            "sufficient": self.sufficient,
            "signal": {
                "samples": sig.samples, "minimum": sig.minimum, "maximum": sig.maximum, "mean": sig.mean,
                "std": sig.std, "crest_factor": number(sig.crest_factor), "max_step": sig.max_step,
                "reversals": sig.reversals, "pe_order": sig.pe_order, "pe_max_order": sig.pe_max_order,
                "pe_condition": [number(c) for c in sig.pe_condition],
            },
            "needed_order": self.needed_order,
            "verdicts": [v.to_dict() for v in self.verdicts],
        }  # fmt: skip
        tm = self.through_model
        if tm is not None:
            out["through_model"] = {
                "model": tm.model.to_dict(),
                "shares": {"up": tm.share_up, "down": tm.share_down, "memory": tm.share_memory},
                "reversals": tm.reversals, "line_switches": tm.line_switches, "update_share": tm.update_share,
                "gamma": tm.gamma, "beta": tm.beta, "trace": tm.trace,
                "condition": number(tm.condition),
                "collinearity": number(tm.collinearity), "weakest": tm.weakest, "x_span": tm.x_span,
                "beyond_crossing": tm.beyond_crossing,
            }  # fmt: skip
        return out


def worst_level(verdicts: Sequence[Verdict]) -> Level:
    """The worst level among ``verdicts`` (``ok`` when there are none)."""
    levels = {v.level for v in verdicts}
    return "insufficient" if "insufficient" in levels else "warning" if "warning" in levels else "ok"


def _reversals(values: np.ndarray) -> int:
    """Changes of sign of the steps of ``values``, zero steps skipped."""
    steps = np.sign(np.diff(values))
    steps = steps[steps != 0.0]
    return int(np.count_nonzero(steps[1:] != steps[:-1]))


def _covariance_conditions(u: np.ndarray, max_order: int) -> tuple[float, ...]:
    """Condition numbers of the ``m x m`` covariance matrices of ``u - mean``, ``m = 1 .. max_order``.

    The covariance method: the rows are ``[u(k), u(k-1), .., u(k-M+1)]`` for
    every ``k`` with a full history (no zero padding), so a signal of exact
    order ``m`` gives an exactly singular ``(m+1) x (m+1)`` matrix instead of
    one merely made regular by the padding.
    """
    dev = u - np.mean(u)
    rows = u.size - max_order + 1
    lagged = np.column_stack([dev[max_order - 1 - j : max_order - 1 - j + rows] for j in range(max_order)])
    cov = lagged.T @ lagged / rows
    out = []
    for m in range(1, max_order + 1):
        eig = np.linalg.eigvalsh(cov[:m, :m])
        out.append(float(eig[-1] / eig[0]) if eig[0] > 0.0 else math.inf)
    return tuple(out)


def input_stats(u: Sequence[float] | np.ndarray, *, max_order: int = DEFAULT_MAX_ORDER) -> InputStats:
    """The input on its own (see :class:`InputStats`).

    Parameters
    ----------
    u : array_like
        The input, finite, at least ``2 max_order`` samples.
    max_order : int
        Highest order of persistent excitation to test, ``>= 1``.
    """
    order_max = validation.integer("max_order", max_order, minimum=1)
    arr = validation.signal("u", u, min_length=2 * order_max)
    std = float(np.std(arr))
    mean = float(np.mean(arr))
    if np.ptp(arr) == 0.0:
        conditions = (math.inf,) * order_max
    else:
        conditions = _covariance_conditions(arr, order_max)
    order = 0
    for c in conditions:
        if c > PE_CONDITION_LIMIT:
            break
        order += 1
    return InputStats(
        samples=int(arr.size), minimum=float(arr.min()), maximum=float(arr.max()), mean=mean, std=std,
        crest_factor=float(np.max(np.abs(arr - mean)) / std) if std > 0.0 else math.inf,
        max_step=float(np.max(np.abs(np.diff(arr)))) if arr.size > 1 else 0.0,
        reversals=_reversals(arr), pe_order=order, pe_max_order=order_max, pe_condition=conditions,
    )  # fmt: skip


def _collinearity(info: np.ndarray, names: tuple[str, ...]) -> tuple[float, str]:
    """Condition number of ``info`` scaled to unit diagonal, and the parameter with the largest variance inflation."""
    diag = np.diag(info)
    if np.any(diag <= 0.0):
        return math.inf, names[int(np.argmin(diag))]
    scale = 1.0 / np.sqrt(diag)
    scaled = info * np.outer(scale, scale)
    eig = np.linalg.eigvalsh(scaled)
    if eig[0] <= SINGULAR_RATIO * eig[-1]:
        # singular: the weakest is the parameter that dominates the null direction
        null = np.linalg.eigh(scaled)[1][:, 0]
        return math.inf, names[int(np.argmax(np.abs(null)))]
    inflation = np.diag(np.linalg.inv(scaled))
    return float(eig[-1] / eig[0]), names[int(np.argmax(inflation))]


def through_model(u: Sequence[float] | np.ndarray, model: BacklashModel) -> ModelExcitation:
    """Run ``u`` through ``model`` noise-free and measure what the estimator would see.

    See :class:`ModelExcitation`; the regressor is built by
    :func:`servoid.excitation.regressor.regressor`.
    """
    if not isinstance(model, BacklashModel):
        raise ConfigError(f"model must be a BacklashModel, got {type(model).__name__}")
    sim = simulate(model, u)
    shares = sim.zone_shares
    on_lines = sim.zone[sim.zone != 0]
    reg = regressor(model, sim)
    info = reg.information()
    eigval = np.linalg.eigvalsh(info)
    gamma, beta = float(max(eigval[0], 0.0)), float(eigval[-1])
    collinearity, weakest = _collinearity(info, reg.names)
    return ModelExcitation(
        model=model, share_up=shares["up"], share_down=shares["down"], share_memory=shares["memory"],
        reversals=_reversals(sim.x), line_switches=int(np.count_nonzero(on_lines[1:] != on_lines[:-1])),
        update_share=float(np.mean(reg.phi)), gamma=gamma, beta=beta, trace=float(np.trace(info)),
        condition=beta / gamma if gamma > 0.0 else math.inf, collinearity=collinearity, weakest=weakest,
        x_span=float(np.percentile(sim.x, 99.5) - np.percentile(sim.x, 0.5)), beyond_crossing=sim.beyond_crossing, simulation=sim,
    )  # fmt: skip


def _signal_verdicts(sig: InputStats, needed: int | None) -> list[Verdict]:
    topic = "excitation order"
    if sig.pe_order == 0:
        return [Verdict("insufficient", topic, "the input is constant: it excites nothing")]
    shown = f">= {sig.pe_order}" if sig.pe_order == sig.pe_max_order else str(sig.pe_order)
    if needed is None:
        return [Verdict("ok", topic, f"persistently exciting of order {shown}")]
    if sig.pe_order < needed:
        return [Verdict(
            "insufficient", topic,
            f"persistently exciting of order {shown} only; the linear block has {needed} parameters "
            f"(na + nb + 1) and needs order >= {needed}: add frequencies (more sines, a wider band, a shorter hold)",
        )]  # fmt: skip
    cond = sig.pe_condition[needed - 1]
    if cond > PE_CONDITION_WARN:
        return [Verdict(
            "warning", topic,
            f"order {shown}, but the {needed}x{needed} covariance matrix is poorly conditioned "
            f"({cond:.3g} > {PE_CONDITION_WARN:g}): the input changes slowly against the sample rate; "
            "shorten the hold or widen the band",
        )]  # fmt: skip
    return [Verdict("ok", topic, f"persistently exciting of order {shown} (needs {needed}; condition {cond:.3g})")]


def _advice(parameter: str) -> str:
    """What to change when ``parameter`` is the least excited one."""
    if parameter in ("m2", "c1", "c2"):
        return "x must travel further along both lines of the backlash: raise the amplitude"
    return "the linear block needs a richer input: add frequencies or shorten the hold"


def _model_verdicts(sig: InputStats, tm: ModelExcitation) -> list[Verdict]:
    model = tm.model
    play = model.dead_zone
    half_range = 0.5 * (sig.maximum - sig.minimum)
    # x scales with the input's amplitude: the amplitude at which x would span the play
    reach = f"~{half_range * play / tm.x_span:.3g}" if tm.x_span > 0.0 else "a level that moves x at all"
    out: list[Verdict] = []
    if tm.line_switches == 0:
        sides = [side for side, share in (("up", tm.share_up), ("down", tm.share_down)) if share > 0.0]
        if sides and tm.x_span > play:
            side = sides[0]
            out.append(Verdict(
                "insufficient", "zones",
                f"the output moves only on the {side} line and never crosses the play back, so "
                f"c{2 if side == 'up' else 1} cannot be seen: reverse the direction of the input, or centre it "
                "(offset) so that x travels both ways through the play",
            ))  # fmt: skip
        else:
            out.append(Verdict(
                "insufficient", "zones",
                f"the input never leaves the memory zone: x swings over {tm.x_span:.3g} against the play "
                f"c1 + c2 = {play:.3g}; raise the amplitude well above {reach} (now ~{half_range:.3g})",
            ))  # fmt: skip
        return out
    if tm.line_switches < MIN_LINE_SWITCHES:
        out.append(Verdict(
            "insufficient", "zones",
            f"the output crossed the play from one line to the other only {tm.line_switches} time(s) "
            f"(needs >= {MIN_LINE_SWITCHES}); {100 * tm.share_memory:.0f}% of the samples sit in the memory "
            f"zone: raise the amplitude (x spans {tm.x_span:.3g} against c1 + c2 = {play:.3g}), shorten the "
            "hold, or run longer",
        ))  # fmt: skip
    if tm.collinearity > COLLINEARITY_WARN:
        # A poorly separated backlash parameter defeats the estimator; a poorly
        # separated linear block only needs more samples (the refinement copes).
        backlash = tm.weakest in ("m2", "c1", "c2")
        singular = math.isinf(tm.collinearity)
        level: Level = "insufficient" if singular or (backlash and tm.collinearity > COLLINEARITY_LIMIT) else "warning"
        out.append(Verdict(
            level, "information",
            "the information matrix of the regressor (eq. 25) is "
            + ("singular: the input tells nothing about " if singular else
               f"poorly conditioned (collinearity {tm.collinearity:.3g} > "
               f"{COLLINEARITY_LIMIT if level == 'insufficient' else COLLINEARITY_WARN:g}): the input tells ")
            + f"{tm.weakest}{'' if singular else ' poorly apart from the other parameters'}; {_advice(tm.weakest)}",
        ))  # fmt: skip
    if tm.share_memory > MEMORY_SHARE_WARN and not any(v.level == "insufficient" for v in out):
        out.append(Verdict(
            "warning", "zones",
            f"{100 * tm.share_memory:.0f}% of the samples sit in the memory zone, where the MRGIA learns "
            "nothing (Phi = 0): the online estimate tends to stall and the model rests on the offline "
            "refinement; raise the amplitude, shorten the hold, or run longer",
        ))  # fmt: skip
    if tm.beyond_crossing:
        out.append(Verdict(
            "warning", "range",
            f"x passes the crossing of the up and down lines (x = {model.lines_cross_at:.3g}) on "
            f"{tm.beyond_crossing} samples, where the paper's model is ambiguous: Remark 2 asks for an input "
            "as small as will do; lower the amplitude or move the offset",
        ))  # fmt: skip
    if not out:
        out.append(Verdict(
            "ok", "zones",
            f"up {100 * tm.share_up:.0f}% / down {100 * tm.share_down:.0f}% / memory {100 * tm.share_memory:.0f}% "
            f"of samples, {tm.line_switches} crossings of the play; collinearity {tm.collinearity:.3g}",
        ))  # fmt: skip
    return out


def assess(
    u: Sequence[float] | np.ndarray,
    *,
    model: BacklashModel | None = None,
    needed_order: int | None = None,
    max_order: int | None = None,
) -> ExcitationReport:
    """The persistent-excitation report of ``u``, alone and (optionally) through ``model``.

    Parameters
    ----------
    u : array_like
        The input, unit of the command.
    model : BacklashModel, optional
        A prior guess or an identified model to run ``u`` through.
    needed_order : int, optional
        Order of persistent excitation required; default ``na + nb + 1`` of
        ``model`` (the parameters of its linear block), none without a model.
    max_order : int, optional
        Highest order tested; default ``max(10, 2 needed_order)``.

    Returns
    -------
    ExcitationReport
        With its verdicts, the worst first.
    """
    if needed_order is None and model is not None:
        needed_order = model.na + model.nb + 1
    needed = None if needed_order is None else validation.integer("needed_order", needed_order, minimum=1)
    top = max(DEFAULT_MAX_ORDER, 2 * (needed or 0)) if max_order is None else max_order
    sig = input_stats(u, max_order=top)
    verdicts = _signal_verdicts(sig, needed)
    tm = through_model(u, model) if model is not None else None
    if tm is not None and sig.pe_order > 0:
        verdicts += _model_verdicts(sig, tm)
    rank = {"insufficient": 0, "warning": 1, "ok": 2}
    verdicts.sort(key=lambda v: rank[v.level])
    return ExcitationReport(signal=sig, through_model=tm, needed_order=needed, verdicts=tuple(verdicts))
