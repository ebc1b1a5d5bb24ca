"""The library of candidate physical effects: what each one (named in :mod:`.effect_names`) does to the model.

Each effect is a small parametric block added to the pseudo-Wiener model
(linear block, then backlash) of :mod:`servoid.ident.models.pseudo_wiener`. Input-side effects
act on ``u`` before the linear block, the friction acts on the linear block's
input without the transport delay, the structural effects change the linear
block itself::

    u --[input_saturation]--[dead_zone]--> w
    x(k) = -sum a_i x(k-i) + sum b_j ( w(k-d-j) - F_c s(k-j) )     (coulomb_friction: F_c, s)
         with A(q), B(q), d changed by extra_pole and extra_delay
    y = backlash(x)

``coulomb_friction``
    A force opposing the direction of motion at the linear block's input:
    ``F_c s(k)`` is subtracted from the input, ``s(k) = sign(x(k-1) - x(k-2))``
    the direction of the linear block's last move (0 when it stood still).
    ``F_c`` is in the unit of ``u``: the command the friction eats. It acts
    without the transport delay ``d`` (it is a force on the mechanism, not a
    command), through the same dynamics ``B(q)/A(q)``.
``input_saturation``
    The drive's limit: ``w = clip(u, -L, L)``; ``L`` in the unit of ``u``.
``dead_zone``
    An input dead band of half-width ``delta`` (unit of ``u``):
    ``w = 0`` for ``|u| <= delta``, else ``u - delta sign(u)``.
``extra_delay``
    The true delay is ``d + m`` samples (``m`` >= 1, an integer: searched,
    not fitted by gradient).
``extra_pole``
    The linear block needs one more real pole ``p`` (``|p| < 1``), added with
    unit static gain: ``A(q) -> A(q)(1 - p q^-1)``, ``B(q) -> (1 - p) B(q)``.

What cannot be told apart (see ``docs/diagnose.md``): a constant *output*
offset ``o`` is absorbed exactly by the backlash (``c1 -> c1 - o``,
``c2 -> c2 + o/m2`` give the same up and down lines), and so is a constant
*input* (force) offset (it shifts ``x`` by a constant); neither is a
candidate. A dead zone and Coulomb friction both remove a band of small
forces and are the closest pair of the library; the benchmark
``benchmarks/diagnose_hidden_effects.py`` measures how often they are
confused.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from servoid.errors import ModelError
from servoid.ident.models.effect_names import (
    CANDIDATE_NAMES,
    COULOMB_FRICTION,
    DEAD_ZONE,
    EFFECT_NAMES,
    EXTRA_DELAY,
    EXTRA_POLE,
    INPUT_SATURATION,
    NONE,
    SUMMARIES,
)

__all__ = [
    "NONE",
    "COULOMB_FRICTION",
    "INPUT_SATURATION",
    "DEAD_ZONE",
    "EXTRA_DELAY",
    "EXTRA_POLE",
    "EFFECT_NAMES",
    "CANDIDATE_NAMES",
    "Effect",
    "EFFECTS",
    "KernelArgs",
    "get_effect",
]


@dataclass(frozen=True)
class KernelArgs:
    """Everything the extended simulation kernel needs, after the effects are applied.

    Attributes
    ----------
    a, b : ndarray
        Linear block (eq. 1), possibly with an extra pole folded in.
    delay : int
        Transport delay of the command, in samples.
    m2, c1, c2 : float
        The backlash.
    saturation : float
        Input limit ``L`` (``inf``: none).
    dead_band : float
        Input dead-band half-width (0: none).
    friction : float
        Coulomb friction ``F_c`` in the unit of ``u`` (0: none).
    """

    a: np.ndarray
    b: np.ndarray
    delay: int
    m2: float
    c1: float
    c2: float
    saturation: float = np.inf
    dead_band: float = 0.0
    friction: float = 0.0


@dataclass(frozen=True)
class Effect:
    """One candidate effect: its parameters, their units and how it changes the model.

    Attributes
    ----------
    name : str
        One of :data:`EFFECT_NAMES`.
    parameters : tuple of str
        Names of its parameters (keys of ``effect_parameters``).
    units : tuple of str
        Unit of each parameter: ``"u"`` (unit of the input), ``"samples"`` or ``""``.
    acts_on : str
        ``"input"``, ``"linear block"``: where the block sits.
    summary : str
        One line for reports and ``--help``.
    apply : callable
        ``apply(args, values) -> KernelArgs``: the kernel arguments with this effect added.
    starts : callable
        ``starts(u, error_u) -> [values, ...]``: starting values for the fit, from the
        training input and the current model's rms error in the unit of ``u``.
    bounds : callable
        ``bounds(u) -> (lower, upper)`` for the fit.
    integer : bool
        Its parameter is an integer searched over :attr:`choices` (not fitted by gradient).
    choices : tuple of int
        The integer values tried, when :attr:`integer`.
    """

    name: str
    parameters: tuple[str, ...]
    units: tuple[str, ...]
    acts_on: str
    summary: str
    apply: Callable[[KernelArgs, np.ndarray], KernelArgs] = dataclasses.field(repr=False)
    starts: Callable[[np.ndarray, float], list[np.ndarray]] = dataclasses.field(repr=False)
    bounds: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] = dataclasses.field(repr=False)
    integer: bool = False
    choices: tuple[int, ...] = ()

    @property
    def n_params(self) -> int:
        """Number of parameters it adds (the penalty of model selection counts these)."""
        return len(self.parameters)

    def check(self, values: Mapping[str, float]) -> np.ndarray:
        """The parameter vector from ``{name: value}``, validated.

        Raises
        ------
        ModelError
            Missing, unknown or out-of-range parameters (named).
        """
        missing = [p for p in self.parameters if p not in values]
        unknown = sorted(set(values) - set(self.parameters))
        if missing or unknown:
            raise ModelError(
                f"effect {self.name!r} takes parameters {', '.join(self.parameters)}; "
                f"missing {missing or 'none'}, unknown {unknown or 'none'}"
            )
        try:
            vec = np.array([float(values[p]) for p in self.parameters], dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"effect {self.name!r}: parameters must be numbers ({exc})") from None
        if not np.all(np.isfinite(vec)):
            raise ModelError(f"effect {self.name!r}: parameters {dict(values)} must be finite")
        _VALID[self.name](vec)
        return vec


def _must(ok: bool, message: str) -> None:
    if not ok:
        raise ModelError(message)


# -- the blocks ------------------------------------------------------------------


def _apply_friction(args: KernelArgs, v: np.ndarray) -> KernelArgs:
    return dataclasses.replace(args, friction=float(v[0]))


def _apply_saturation(args: KernelArgs, v: np.ndarray) -> KernelArgs:
    return dataclasses.replace(args, saturation=float(v[0]))


def _apply_dead_zone(args: KernelArgs, v: np.ndarray) -> KernelArgs:
    return dataclasses.replace(args, dead_band=float(v[0]))


def _apply_delay(args: KernelArgs, v: np.ndarray) -> KernelArgs:
    return dataclasses.replace(args, delay=args.delay + int(round(float(v[0]))))


def _apply_pole(args: KernelArgs, v: np.ndarray) -> KernelArgs:
    p = float(v[0])
    # A(q)(1 - p q^-1) in coefficient form [1, a1, .., an] * [1, -p]; (1 - p) keeps the static gain.
    a_ext = np.convolve(np.concatenate(([1.0], args.a)), [1.0, -p])[1:]
    return dataclasses.replace(args, a=a_ext, b=(1.0 - p) * args.b)


# Starting values and bounds are set from the data: the input's scale |u| and
# ``error_u``, the current model's rms free-run error expressed in the unit of
# u (divided by the static gain). An effect whose start lies where it has no
# influence (a saturation above max|u|) has a zero gradient there, and one
# started far too strong lands in a poor local minimum, so each effect gets a
# few starts spread over its plausible range.


def _u_scale(u: np.ndarray) -> float:
    return max(float(np.max(np.abs(u))), 1e-12)


def _friction_starts(u: np.ndarray, error_u: float) -> list[np.ndarray]:
    s = _u_scale(u)
    values = {min(0.5 * error_u, 0.5 * s), min(2.0 * error_u, 0.5 * s), 0.02 * s}
    return [np.array([v]) for v in sorted(values) if v > 0.0]


def _friction_bounds(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.array([0.0]), np.array([_u_scale(u)])


def _saturation_starts(u: np.ndarray, error_u: float) -> list[np.ndarray]:
    au = np.abs(u)
    return [np.array([float(np.quantile(au, q))]) for q in (0.97, 0.85, 0.6)]


def _saturation_bounds(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = _u_scale(u)
    return np.array([1e-3 * s]), np.array([1.5 * s])


def _dead_zone_starts(u: np.ndarray, error_u: float) -> list[np.ndarray]:
    au = np.abs(u)
    values = {float(np.quantile(au, q)) for q in (0.03, 0.15)} | {min(error_u, 0.5 * _u_scale(u))}
    return [np.array([v]) for v in sorted(values) if v > 0.0]


def _dead_zone_bounds(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.array([0.0]), np.array([0.9 * _u_scale(u)])


def _pole_starts(u: np.ndarray, error_u: float) -> list[np.ndarray]:
    return [np.array([0.3]), np.array([0.7]), np.array([0.9])]


def _pole_bounds(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.array([-0.95]), np.array([0.995])


def _no_starts(u: np.ndarray, error_u: float) -> list[np.ndarray]:
    return []


def _no_bounds(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.array([1.0]), np.array([np.inf])


def _valid_friction(v: np.ndarray) -> None:
    _must(v[0] >= 0.0, f"coulomb_friction: force (={v[0]!r}) must be >= 0")


def _valid_saturation(v: np.ndarray) -> None:
    _must(v[0] > 0.0, f"input_saturation: limit (={v[0]!r}) must be > 0")


def _valid_dead_zone(v: np.ndarray) -> None:
    _must(v[0] >= 0.0, f"dead_zone: width (={v[0]!r}) must be >= 0")


def _valid_delay(v: np.ndarray) -> None:
    _must(float(v[0]).is_integer() and v[0] >= 1, f"extra_delay: samples (={v[0]!r}) must be an integer >= 1")


def _valid_pole(v: np.ndarray) -> None:
    _must(abs(v[0]) < 1.0, f"extra_pole: pole (={v[0]!r}) must satisfy |pole| < 1")


_VALID: dict[str, Callable[[np.ndarray], None]] = {
    COULOMB_FRICTION: _valid_friction,
    INPUT_SATURATION: _valid_saturation,
    DEAD_ZONE: _valid_dead_zone,
    EXTRA_DELAY: _valid_delay,
    EXTRA_POLE: _valid_pole,
}

#: The library, in the order candidates are tried and reported.
EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(COULOMB_FRICTION, ("force",), ("u",), "linear block input",
               SUMMARIES[COULOMB_FRICTION],
               _apply_friction, _friction_starts, _friction_bounds),
        Effect(INPUT_SATURATION, ("limit",), ("u",), "input",
               SUMMARIES[INPUT_SATURATION],
               _apply_saturation, _saturation_starts, _saturation_bounds),
        Effect(DEAD_ZONE, ("width",), ("u",), "input",
               SUMMARIES[DEAD_ZONE],
               _apply_dead_zone, _dead_zone_starts, _dead_zone_bounds),
        Effect(EXTRA_DELAY, ("samples",), ("samples",), "linear block",
               SUMMARIES[EXTRA_DELAY],
               _apply_delay, _no_starts, _no_bounds, integer=True, choices=(1, 2, 3)),
        Effect(EXTRA_POLE, ("pole",), ("",), "linear block",
               SUMMARIES[EXTRA_POLE],
               _apply_pole, _pole_starts, _pole_bounds),
    )
}  # fmt: skip


def get_effect(name: str) -> Effect:
    """The effect called ``name``; :class:`ModelError` naming the valid ones otherwise."""
    try:
        return EFFECTS[name]
    except KeyError:
        raise ModelError(f"unknown effect {name!r}; known: {', '.join(CANDIDATE_NAMES)}") from None
