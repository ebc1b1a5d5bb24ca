"""The pseudo-Wiener model with output backlash, eqs (1)-(11) of the paper.

A linear block (eq. 1)::

    x(k) = -sum_{i=1..na} a_i x(k-i) + sum_{j=0..nb} b_j u(k-d-j)

is followed by a backlash with slopes ``m1 = 1`` (up line) and ``m2`` (down
line) and dead zones ``c1`` and ``c2`` (eqs 2-8)::

    up line    y = m1 (x - c1)     reached when x rises past y(k-1)/m1 + c1   (eq. 6)
    down line  y = m2 (x + c2)     reached when x falls below y(k-1)/m2 - c2  (eq. 7)
    otherwise  y = y(k-1)          the memory zone

Units: ``u`` is in the unit of the command, ``x`` and ``y`` in the unit of the
measured position (rad, encoder counts or the user's unit, as recorded); the
dead zones ``c1`` and ``c2`` are in the unit of ``x``. Time is in samples.

Where the lines cross
---------------------
With ``m2 != 1`` the up and down lines cross at ``x* = (c1 + m2 c2)/(1 - m2)``
(:attr:`BacklashModel.lines_cross_at`; ``x* = -4`` for the paper's example).
Beyond ``x*`` the memory zone of eq. (6)-(7) is empty and both switching
functions can be 1 at once: the paper's eq. (8) does not say which line holds.
servoid lets the direction of motion choose: rising ``x`` follows the up line,
falling ``x`` the down line, standing ``x`` holds (see
:func:`servoid.ident.models.kernels.backlash_step`). This is the classic play
operator wherever the lines do not cross, and it stays single-valued and
causal beyond ``x*``, where a reversal then jumps between the lines.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ModelError
from servoid.ident.models.kernels import schur_stable

__all__ = ["BacklashModel", "M1", "ThetaLayout", "backlash_offset", "within_stability_margin"]

#: Slope of the up line; fixed to one to normalise the model (text after eq. 11).
M1 = 1.0

#: A linear block whose largest pole magnitude reaches this bound is rejected as unstable.
_STABILITY_MARGIN = 1.0 - 1e-9


def within_stability_margin(a: np.ndarray) -> bool:
    """Whether :class:`BacklashModel` accepts the linear block ``a``: every pole inside ``|p| < 1 - 1e-9``.

    The roots of ``z^na + a_1 z^(na-1) + ... + a_na`` lie inside radius ``r``
    exactly when those of the polynomial scaled by ``a_i / r^i`` lie inside the
    unit circle, so the Schur-Cohn test of the scaled coefficients decides it
    without root finding. A fit that tests plain ``|p| < 1`` can stop in
    between, a pole at ``-1 + 1e-10``, and then cannot be made a model.

    Parameters
    ----------
    a : ndarray
        The denominator's coefficients ``a_1 .. a_na``.
    """
    scaled = np.asarray(a, dtype=np.float64) / _STABILITY_MARGIN ** np.arange(1, len(a) + 1)
    return bool(schur_stable(np.ascontiguousarray(scaled)))


def backlash_offset(na: int, nb: int) -> int:
    """Index of ``m2 - 1`` in theta (eq. 15); ``c1`` and ``c2`` follow it.

    Plain integer arithmetic, so that the compiled kernels use this very function.
    """
    return na + nb + 1


@dataclass(frozen=True)
class ThetaLayout:
    """Where each parameter sits in ``theta = [a_1..a_na, b_0..b_nb, m2 - 1, c1, c2]`` (eq. 15).

    The one place for this layout: the estimator's state, its results, the
    refinement and the reports all index theta through it.

    Parameters
    ----------
    na, nb : int
        Orders of the linear block.
    """

    na: int
    nb: int

    @property
    def n(self) -> int:
        """Length of theta, ``na + nb + 4``."""
        return self.na + self.nb + 4

    @property
    def a(self) -> slice:
        """``a_1 .. a_na``."""
        return slice(0, self.na)

    @property
    def b(self) -> slice:
        """``b_0 .. b_nb``."""
        return slice(self.na, self.na + self.nb + 1)

    @property
    def m2(self) -> int:
        """Index of ``m2 - 1`` (in theta) or ``m2`` (in :meth:`values`)."""
        return backlash_offset(self.na, self.nb)

    @property
    def c1(self) -> int:
        """Index of ``c1``."""
        return self.m2 + 1

    @property
    def c2(self) -> int:
        """Index of ``c2``."""
        return self.m2 + 2

    @property
    def backlash(self) -> slice:
        """``m2 - 1, c1, c2``."""
        return slice(self.m2, self.n)

    @property
    def names(self) -> tuple[str, ...]:
        """``a1.., b0.., m2, c1, c2`` (the entry for ``m2 - 1`` is named ``m2``: reports show ``m2`` itself)."""
        return (*(f"a{i + 1}" for i in range(self.na)), *(f"b{j}" for j in range(self.nb + 1)), "m2", "c1", "c2")

    def values(self, theta: np.ndarray) -> np.ndarray:
        """Theta (or rows of thetas, last axis) with ``m2 - 1`` turned into ``m2``; a copy."""
        out = np.array(theta, dtype=np.float64)
        out[..., self.m2] += M1
        return out

    def theta(self, values: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`values`; a copy."""
        out = np.array(values, dtype=np.float64)
        out[..., self.m2] -= M1
        return out


def _coefficients(name: str, values: Sequence[float] | np.ndarray, *, minimum: int) -> tuple[float, ...]:
    try:
        arr = np.atleast_1d(np.asarray(values, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{name} (={values!r}) must be a sequence of numbers") from exc
    if arr.ndim != 1:
        raise ModelError(f"{name} must be a flat sequence, got shape {arr.shape}")
    if arr.size < minimum:
        raise ModelError(f"{name} (={tuple(arr.tolist())}) needs at least {minimum} coefficient(s)")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{name} (={tuple(arr.tolist())}) must be finite")
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class BacklashModel:
    """A linear block followed by an output backlash (the paper's eqs 1-11).

    Parameters
    ----------
    a : sequence of float
        Denominator coefficients ``a_1 .. a_na`` of eq. (1), ``na >= 1``. The
        linear block must be stable (all poles strictly inside the unit circle).
    b : sequence of float
        Numerator coefficients ``b_0 .. b_nb`` of eq. (1), ``nb >= 0``; not all zero.
    delay : int
        Input delay ``d >= 1`` in samples.
    m2 : float
        Slope of the down line, ``> 0`` (``m1`` is fixed to 1).
    c1, c2 : float
        Dead zones of the up and down lines, ``> 0``, in the unit of ``x``.

    Raises
    ------
    ModelError
        For any parameter outside these ranges; the message names the value.

    Notes
    -----
    The parameter vector of eq. (15) is ``theta = [a, b, m2 - 1, c1, c2]``
    (:attr:`theta`, :meth:`from_theta`).
    """

    a: tuple[float, ...]
    b: tuple[float, ...]
    delay: int
    m2: float
    c1: float
    c2: float
    _poles: tuple[complex, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        a = _coefficients("a", self.a, minimum=1)
        b = _coefficients("b", self.b, minimum=1)
        try:
            delay = validation.integer("delay", self.delay, minimum=1)
            m2 = validation.positive("m2", self.m2)
            c1 = validation.positive("c1", self.c1)
            c2 = validation.positive("c2", self.c2)
        except ValueError as exc:
            raise ModelError(str(exc)) from None
        if not any(b):
            raise ModelError(f"b (={b}) is all zero: the linear block ignores its input")
        poles = tuple(complex(p) for p in np.roots(np.concatenate(([1.0], a))))
        worst = max(poles, key=abs)
        if abs(worst) >= _STABILITY_MARGIN:
            raise ModelError(
                f"the linear block with a (={a}) is unstable: pole {worst:.4g} has "
                f"|p| = {abs(worst):.4g}, all poles must satisfy |p| < 1"
            )
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "delay", delay)
        object.__setattr__(self, "m2", m2)
        object.__setattr__(self, "c1", c1)
        object.__setattr__(self, "c2", c2)
        object.__setattr__(self, "_poles", poles)

    # -- structure ---------------------------------------------------------------
    @property
    def m1(self) -> float:
        """Slope of the up line, fixed to 1 (normalisation after eq. 11)."""
        return M1

    @property
    def na(self) -> int:
        """Order ``n_a`` of the denominator."""
        return len(self.a)

    @property
    def nb(self) -> int:
        """Order ``n_b`` of the numerator (``len(b) - 1``)."""
        return len(self.b) - 1

    @property
    def n_params(self) -> int:
        """Length of :attr:`theta`: ``na + nb + 1 + 3``."""
        return self.na + self.nb + 4

    @property
    def poles(self) -> tuple[complex, ...]:
        """Poles of the linear block (roots of ``z^na + a_1 z^(na-1) + ... + a_na``)."""
        return self._poles

    @property
    def dc_gain(self) -> float:
        """Steady-state gain ``sum(b) / (1 + sum(a))`` of the linear block (x per unit u)."""
        return float(sum(self.b) / (1.0 + sum(self.a)))

    @property
    def dead_zone(self) -> float:
        """Total width ``c1 + c2`` of the backlash play, in the unit of ``x``."""
        return self.c1 + self.c2

    @property
    def lines_cross_at(self) -> float | None:
        """``x`` where the up and down lines cross, or ``None`` when ``m2 == 1``.

        Beyond this point the paper's switching rule is ambiguous; see the
        module docstring for the rule servoid applies there.
        """
        if self.m2 == M1:
            return None
        return (M1 * self.c1 + self.m2 * self.c2) / (M1 - self.m2)

    # -- parameter vector (eq. 15) ------------------------------------------------
    @property
    def layout(self) -> ThetaLayout:
        """Where each parameter sits in :attr:`theta`."""
        return ThetaLayout(self.na, self.nb)

    @property
    def theta(self) -> np.ndarray:
        """Parameter vector ``[a_1..a_na, b_0..b_nb, m2 - 1, c1, c2]`` of eq. (15)."""
        return self.layout.theta(self.values())

    @classmethod
    def from_theta(cls, theta: Sequence[float] | np.ndarray, *, na: int, nb: int, delay: int) -> BacklashModel:
        """Build a model from the parameter vector of eq. (15).

        Raises
        ------
        ModelError
            If ``theta`` has the wrong length or gives an invalid model.
        """
        th = np.asarray(theta, dtype=np.float64).ravel()
        lay = ThetaLayout(na, nb)
        if th.size != lay.n:
            raise ModelError(f"theta has {th.size} entries, na={na} and nb={nb} need {lay.n}")
        return cls(
            a=tuple(th[lay.a]),
            b=tuple(th[lay.b]),
            delay=delay,
            m2=float(th[lay.m2]) + M1,
            c1=float(th[lay.c1]),
            c2=float(th[lay.c2]),
        )

    @staticmethod
    def parameter_names(na: int, nb: int) -> tuple[str, ...]:
        """Names of the entries of :attr:`theta` for orders ``na``, ``nb``: ``a1.., b0.., m2, c1, c2``.

        The entry for ``m2 - 1`` is named ``m2`` because reports show ``m2`` itself.
        """
        return ThetaLayout(na, nb).names

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names for this model's orders (see :meth:`parameter_names`)."""
        return self.parameter_names(self.na, self.nb)

    def values(self) -> np.ndarray:
        """Parameter values in the order of :attr:`names`, with ``m2`` itself (not ``m2 - 1``)."""
        return np.array([*self.a, *self.b, self.m2, self.c1, self.c2], dtype=np.float64)

    def max_relative_error(self, truth: BacklashModel) -> float:
        """Largest ``|p - p_true| / |p_true|`` over the parameters, ``m2`` itself included.

        This is the paper's "maximum relative error of the parameters" (Section 4).
        """
        if (self.na, self.nb) != (truth.na, truth.nb):
            raise ModelError(f"orders differ: (na, nb) = ({self.na}, {self.nb}) against ({truth.na}, {truth.nb})")
        ref = truth.values()
        scale = np.where(ref != 0.0, np.abs(ref), 1.0)
        return float(np.max(np.abs(self.values() - ref) / scale))

    def to_control(self, dt: float | bool = True) -> Any:
        """The linear block as a python-control ``TransferFunction`` (:func:`servoid.ident.models.linear_block.to_control`).

        Parameters
        ----------
        dt : float or True
            Sample period in seconds; ``True`` when it is not known.
        """
        from servoid.ident.models.linear_block import to_control

        return to_control(self, dt)

    def __repr__(self) -> str:
        def g(values: tuple[float, ...]) -> str:
            return "(" + ", ".join(f"{v:.6g}" for v in values) + ("," if len(values) == 1 else "") + ")"

        return (
            f"BacklashModel(a={g(self.a)}, b={g(self.b)}, delay={self.delay}, "
            f"m2={self.m2:.6g}, c1={self.c1:.6g}, c2={self.c2:.6g})"
        )

    # -- serialisation -------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict: ``{"a", "b", "delay", "m1", "m2", "c1", "c2"}``."""
        return {
            "a": list(self.a),
            "b": list(self.b),
            "delay": self.delay,
            "m1": M1,
            "m2": self.m2,
            "c1": self.c1,
            "c2": self.c2,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> BacklashModel:
        """Inverse of :meth:`to_dict`; missing or unknown keys raise :class:`ModelError`."""
        if not isinstance(data, Mapping):
            raise ModelError(f"a model must be a JSON object, got {type(data).__name__}")
        required = {"a", "b", "delay", "m2", "c1", "c2"}
        missing = sorted(required - set(data))
        if missing:
            raise ModelError(f"model is missing {', '.join(missing)}")
        unknown = sorted(set(data) - required - {"m1"})
        if unknown:
            raise ModelError(f"model has unknown keys {', '.join(unknown)}")
        if "m1" in data and data["m1"] != M1:
            raise ModelError(f"m1 (={data['m1']!r}) must be 1: servoid normalises the up line to slope 1")
        return cls(a=data["a"], b=data["b"], delay=data["delay"], m2=data["m2"], c1=data["c1"], c2=data["c2"])
