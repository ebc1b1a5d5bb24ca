"""The pseudo-Wiener model extended by effects of the library: a first-class model.

An :class:`ExtendedModel` is a :class:`~servoid.ident.models.pseudo_wiener.BacklashModel`
(the *base*) plus zero or more effects of :mod:`servoid.ident.models.effects`, each
with its parameters. It simulates (:func:`simulate_extended`, compiled), it
fits all its parameters jointly to a record (:func:`fit_extended`, the
output-error least squares of :func:`servoid.ident.offline.refine` generalised), and
it serialises to the ``"effects"`` key of ``model.json``
(:meth:`ExtendedModel.effects_json`, :meth:`ExtendedModel.from_json`).

With no effects the simulation is exactly :func:`servoid.ident.free_run`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ModelError
from servoid.ident.metrics import nrmse
from servoid.ident.models.effects import EFFECTS, KernelArgs, get_effect
from servoid.ident.models.kernels import extended_kernel, schur_stable
from servoid.ident.models.pseudo_wiener import BacklashModel, ThetaLayout
from servoid.ident.offline._oefit import failure_residual, fit_output_error, fit_record

__all__ = [
    "AppliedEffect",
    "ExtendedModel",
    "ExtendedSimulation",
    "ExtendedFit",
    "simulate_extended",
    "fit_extended",
    "extended_kernel",
]

#: Smallest dead zone and down-line slope the search may reach, relative to std(y) (as in refine).
_LOWER_BOUND_REL = 1e-9


@dataclass(frozen=True)
class AppliedEffect:
    """An effect of the library with its parameter values.

    Attributes
    ----------
    name : str
        A name of :data:`servoid.ident.models.effects.CANDIDATE_NAMES`.
    values : tuple of float
        Its parameters, in the order of ``EFFECTS[name].parameters``.
    """

    name: str
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        effect = get_effect(self.name)
        vec = np.atleast_1d(np.asarray(self.values, dtype=np.float64))
        if vec.size != effect.n_params:
            raise ModelError(f"effect {self.name!r} takes {effect.n_params} parameter(s), got {vec.size}")
        checked = effect.check(dict(zip(effect.parameters, vec.tolist())))
        object.__setattr__(self, "values", tuple(float(v) for v in checked))

    @classmethod
    def from_parameters(cls, name: str, parameters: Mapping[str, float]) -> AppliedEffect:
        """Build from ``{parameter name: value}`` (the JSON form)."""
        effect = get_effect(name)
        return cls(name, tuple(effect.check(parameters).tolist()))

    @property
    def parameters(self) -> dict[str, float]:
        """``{parameter name: value}``, units in ``EFFECTS[name].units``."""
        return dict(zip(EFFECTS[self.name].parameters, self.values))

    def to_dict(self) -> dict[str, Any]:
        """``{"name": ..., "parameters": {...}}`` as stored under ``"effects"`` in model.json."""
        return {"name": self.name, "parameters": self.parameters}


@dataclass(frozen=True)
class ExtendedModel:
    """A backlash model plus effects of the library.

    Parameters
    ----------
    base : BacklashModel
        Linear block and backlash.
    effects : sequence of AppliedEffect
        At most one of each name; order is kept (the order they were found).

    Raises
    ------
    ModelError
        For a repeated effect.
    """

    base: BacklashModel
    effects: tuple[AppliedEffect, ...] = ()

    def __post_init__(self) -> None:
        effects = tuple(self.effects)
        names = [e.name for e in effects]
        if len(set(names)) != len(names):
            raise ModelError(f"an effect may appear once, got {names}")
        object.__setattr__(self, "effects", effects)

    @property
    def effect_names(self) -> tuple[str, ...]:
        """Names of the effects, in order."""
        return tuple(e.name for e in self.effects)

    def effect(self, name: str) -> AppliedEffect | None:
        """The applied effect called ``name``, or None."""
        for e in self.effects:
            if e.name == name:
                return e
        return None

    def with_effect(self, effect: AppliedEffect) -> ExtendedModel:
        """This model with ``effect`` added (or replaced)."""
        kept = tuple(e for e in self.effects if e.name != effect.name)
        return ExtendedModel(self.base, (*kept, effect))

    @property
    def n_params(self) -> int:
        """All parameters: the base's and every effect's."""
        return self.base.n_params + sum(EFFECTS[e.name].n_params for e in self.effects)

    def kernel_args(self) -> KernelArgs:
        """The arrays and scalars :func:`extended_kernel` runs on."""
        m = self.base
        args = KernelArgs(a=np.asarray(m.a), b=np.asarray(m.b), delay=m.delay, m2=m.m2, c1=m.c1, c2=m.c2)
        for e in self.effects:
            args = EFFECTS[e.name].apply(args, np.asarray(e.values))
        return args

    def to_dict(self) -> dict[str, Any]:
        """The base model's dict with the ``"effects"`` list: ``{"a", ..., "c2", "effects": [...]}``."""
        return {**self.base.to_dict(), "effects": self.effects_json()}

    def effects_json(self) -> list[dict[str, Any]]:
        """The ``"effects"`` list of model.json: ``[{"name": ..., "parameters": {...}}, ...]``."""
        return [e.to_dict() for e in self.effects]

    @classmethod
    def from_json(cls, base: BacklashModel, effects: Any) -> ExtendedModel:
        """Inverse of :meth:`effects_json` (``effects`` may be None: no effects).

        Raises
        ------
        ModelError
            For anything but a list of ``{"name", "parameters"}`` objects with valid values.
        """
        if effects is None:
            return cls(base)
        if not isinstance(effects, list):
            raise ModelError(f"'effects' must be a list of objects, got {type(effects).__name__}")
        out = []
        for i, item in enumerate(effects):
            if not isinstance(item, Mapping) or set(item) != {"name", "parameters"}:
                raise ModelError(f"effects[{i}] must be an object with keys 'name' and 'parameters', got {item!r}")
            if not isinstance(item["parameters"], Mapping):
                raise ModelError(f"effects[{i}].parameters must be an object, got {item['parameters']!r}")
            out.append(AppliedEffect.from_parameters(str(item["name"]), item["parameters"]))
        return cls(base, tuple(out))

    def describe(self) -> str:
        """``"base + coulomb_friction(force=0.3)"``-style one-liner."""
        if not self.effects:
            return "base model (no effect)"
        parts = [f"{e.name}(" + ", ".join(f"{k}={v:.4g}" for k, v in e.parameters.items()) + ")" for e in self.effects]
        return "base + " + " + ".join(parts)


@dataclass(frozen=True)
class ExtendedSimulation:
    """Free-run output of an :class:`ExtendedModel`.

    Attributes
    ----------
    x : ndarray
        Output of the linear block.
    y : ndarray
        Output of the backlash (noise-free).
    zone : ndarray of int8
        ``1`` up line, ``-1`` down line, ``0`` memory zone, per sample.
    """

    x: np.ndarray
    y: np.ndarray
    zone: np.ndarray


def _run(args: KernelArgs, u: np.ndarray, y0: float, x: np.ndarray, y: np.ndarray, zone: np.ndarray) -> None:
    extended_kernel(
        np.ascontiguousarray(args.a), np.ascontiguousarray(args.b), int(args.delay), args.m2, args.c1, args.c2,
        float(args.saturation), float(args.dead_band), float(args.friction), u, y0, x, y, zone,
    )  # fmt: skip


def simulate_extended(model: ExtendedModel, u: Sequence[float] | np.ndarray, *, y0: float = 0.0) -> ExtendedSimulation:
    """Simulate ``model`` from rest on ``u`` (noise-free); ``y0`` is the backlash output before the first sample."""
    u_arr = validation.signal("u", u)
    y0 = validation.real("y0", y0)
    x = np.empty_like(u_arr)
    y = np.empty_like(u_arr)
    zone = np.empty(u_arr.shape, dtype=np.int8)
    _run(model.kernel_args(), u_arr, y0, x, y, zone)
    return ExtendedSimulation(x=x, y=y, zone=zone)


@dataclass(frozen=True)
class ExtendedFit:
    """Result of :func:`fit_extended`.

    Attributes
    ----------
    model : ExtendedModel
        The fitted model.
    initial : ExtendedModel
        Where the search started.
    names : tuple of str
        Names of the fitted parameters: the base's (``a1.., b0.., m2, c1, c2``)
        then ``<effect>.<parameter>`` for each continuous effect parameter.
    stderr : tuple of float
        Standard error of each, NaN where the data do not determine it.
    nrmse : float
        Free-run NRMSE on the record.
    nfev : int
        Simulations used.
    success : bool
        Whether the optimiser reported convergence.
    """

    model: ExtendedModel
    initial: ExtendedModel
    names: tuple[str, ...]
    stderr: tuple[float, ...]
    nrmse: float
    nfev: int
    success: bool

    def stderr_dict(self) -> dict[str, float]:
        """``{name: standard error}``."""
        return dict(zip(self.names, self.stderr))


class _Layout:
    """Maps a flat parameter vector to an :class:`ExtendedModel` of fixed structure."""

    def __init__(self, template: ExtendedModel, u: np.ndarray, y: np.ndarray) -> None:
        base = template.base
        self.na, self.nb, self.delay = base.na, base.nb, base.delay
        self.template = template
        floor = _LOWER_BOUND_REL * max(float(np.std(y)), 1e-12)
        lower = [-np.inf] * (self.na + self.nb + 1) + [floor] * 3
        upper = [np.inf] * (self.na + self.nb + 4)
        names = list(base.names)
        self.free: list[bool] = []  # per effect: whether its parameters are fitted
        for e in template.effects:
            spec = EFFECTS[e.name]
            free = not spec.integer
            self.free.append(free)
            if free:
                lo, hi = spec.bounds(u)
                lower += lo.tolist()
                upper += hi.tolist()
                names += [f"{e.name}.{p}" for p in spec.parameters]
        self.lower = np.array(lower)
        self.upper = np.array(upper)
        self.names = tuple(names)

    def vector(self, model: ExtendedModel) -> np.ndarray:
        parts = [model.base.values()]
        for e, free in zip(model.effects, self.free):
            if free:
                parts.append(np.asarray(e.values))
        return np.concatenate(parts)

    def args(self, p: np.ndarray) -> KernelArgs:
        lay = ThetaLayout(self.na, self.nb)  # the base's values lead p, with m2 itself
        args = KernelArgs(a=p[lay.a], b=p[lay.b], delay=self.delay,
                          m2=float(p[lay.m2]), c1=float(p[lay.c1]), c2=float(p[lay.c2]))  # fmt: skip
        i = lay.n
        for e, free in zip(self.template.effects, self.free):
            spec = EFFECTS[e.name]
            if free:
                values = p[i : i + spec.n_params]
                i += spec.n_params
            else:
                values = np.asarray(e.values)
            args = spec.apply(args, values)
        return args

    def model(self, p: np.ndarray) -> ExtendedModel:
        lay = ThetaLayout(self.na, self.nb)
        base = BacklashModel(a=tuple(p[lay.a]), b=tuple(p[lay.b]), delay=self.delay,
                             m2=float(p[lay.m2]), c1=float(p[lay.c1]), c2=float(p[lay.c2]))  # fmt: skip
        effects = []
        i = lay.n
        for e, free in zip(self.template.effects, self.free):
            n = EFFECTS[e.name].n_params
            if free:
                effects.append(AppliedEffect(e.name, tuple(p[i : i + n].tolist())))
                i += n
            else:
                effects.append(e)
        return ExtendedModel(base, tuple(effects))


class _ExtendedOutputError:
    """Residual ``y_hat(p) - y`` of the extended model's free run, for the optimiser."""

    def __init__(self, layout: _Layout, u: np.ndarray, y: np.ndarray, y0: float) -> None:
        self.layout, self.u, self.y, self.y0 = layout, u, y, y0
        self.x = np.empty_like(u)
        self.y_hat = np.empty_like(u)
        self.zone = np.empty(u.shape, dtype=np.int8)
        self.penalty = failure_residual(y)

    def __call__(self, p: np.ndarray) -> np.ndarray:
        args = self.layout.args(p)
        if not schur_stable(np.ascontiguousarray(args.a)):
            return self.penalty
        _run(args, self.u, self.y0, self.x, self.y_hat, self.zone)
        out: np.ndarray = self.y_hat - self.y
        if not np.all(np.isfinite(out)):
            return self.penalty
        return out


def fit_extended(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    initial: ExtendedModel,
    *,
    y0: float | None = None,
    max_nfev: int | None = None,
) -> ExtendedFit:
    """Fit every continuous parameter of ``initial`` (base and effects) jointly to ``(u, y)``.

    Parameters
    ----------
    u, y : array_like
        The record, same length, finite.
    initial : ExtendedModel
        Start and structure: orders, delay and which effects (integer effect
        parameters such as ``extra_delay`` are kept as given).
    y0 : float, optional
        Backlash output before the first sample; default ``y[0]``.
    max_nfev : int, optional
        Cap on the number of simulations.

    Returns
    -------
    ExtendedFit

    Notes
    -----
    The same simulation-error least squares as :func:`servoid.ident.offline.refine`
    (shared in :mod:`servoid.ident.offline._oefit`): bounds keep ``m2``, ``c1``,
    ``c2`` positive and each effect parameter in its physical range
    (:attr:`servoid.ident.models.effects.Effect.bounds`); an unstable linear block
    gets a large constant residual.
    """
    u_arr, y_arr, start_y = fit_record(u, y, initial.n_params, y0)
    layout = _Layout(initial, u_arr, y_arr)
    problem = _ExtendedOutputError(layout, u_arr, y_arr, start_y)
    fit = fit_output_error(problem, layout.vector(initial), layout.lower, layout.upper, max_nfev=max_nfev)
    try:
        model = layout.model(fit.x)
    except ModelError:
        # The optimiser ended on the penalty plateau: keep the start.
        model = initial
    y_hat = simulate_extended(model, u_arr, y0=start_y).y
    return ExtendedFit(
        model=model,
        initial=initial,
        names=layout.names,
        stderr=tuple(float(s) for s in fit.stderr),
        nrmse=nrmse(y_arr, y_hat),
        nfev=fit.nfev,
        success=fit.success,
    )
