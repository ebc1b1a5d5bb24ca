"""What an excitation signal is: one frozen, validated spec per kind, and its text form.

A spec is written ``kind:key=value,key=value`` (``prbs:amplitude=1.5,hold=3``).
Every kind shares three keys that keep the signal safe:

``amplitude`` (required)
    Half-width of the bound: every sample lies in ``[offset - amplitude,
    offset + amplitude]``, unit of the command ``u``.
``offset`` (default 0)
    The operating point the signal is centred on, unit of ``u``; the signal
    starts there.
``rate`` (default ``inf``, no limit)
    Largest change between consecutive samples, unit of ``u`` per sample.

The other keys belong to one kind (time in samples, frequency in cycles per
sample, 0 to 0.5); each class below documents its keys, and :func:`grammar`
lists them with their defaults:

=========== ================================================================
kind        what it is, and its keys
=========== ================================================================
uniform     uniform bounded white noise, the paper's input (Section 4)
prbs        a maximum-length binary sequence: ``hold``, ``order``
steps       random steps: ``hold``, ``levels``
multisine   equal-amplitude cosines with Schroeder phases: ``bands``, ``period``
chirp       a swept sine: ``f0``, ``f1``, ``period``, ``sweep``
levels      dithered visits to operating levels: ``count``, ``dwell``,
            ``dither``, ``hold``
gentle      gentle sines, segments of a few periods with a low peak
            acceleration (a play inside the loop): ``accel``, ``spread``,
            ``cycles``, ``smallest``
=========== ================================================================

:func:`parse_spec` reads the text form, :func:`format_spec` writes it back
(every key, so that a recording's provenance does not depend on defaults);
``parse_spec(format_spec(s)) == s``.
"""

from __future__ import annotations

import math
import re
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, ClassVar

from servoid import limits, validation
from servoid.errors import ConfigError
from servoid.limits import MAX_LEVELS

__all__ = [
    "SignalSpec",
    "UniformSpec",
    "PRBSSpec",
    "StepsSpec",
    "MultisineSpec",
    "ChirpSpec",
    "LevelsSpec",
    "GentleSpec",
    "KINDS",
    "parse_spec",
    "format_spec",
    "grammar",
]

#: Longest PRBS register; its period of about a million bits outlasts any bench run.
MAX_PRBS_ORDER = 20

#: Longest multisine period, so that one period's table stays small.
MAX_MULTISINE_PERIOD = 1 << 20

_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_BAND = re.compile(rf"\s*({_NUMBER})\s*-\s*({_NUMBER})\s*")
_BANDS = re.compile(rf"{_BAND.pattern}(?:\+{_BAND.pattern})*")


def _hold(name: str, value: Any) -> int:
    return validation.integer(name, value, minimum=1)


@dataclass(frozen=True, kw_only=True)
class SignalSpec:
    """Keys every kind shares: the bound and the rate limit.

    Parameters
    ----------
    amplitude : float
        Half-width of the bound around ``offset``, ``> 0``, unit of ``u``.
    offset : float
        Operating point, unit of ``u``; the signal starts there.
    rate : float
        Largest ``|u(k) - u(k-1)|``, ``> 0``, unit of ``u`` per sample;
        ``inf`` for no limit.
    """

    kind: ClassVar[str] = ""

    amplitude: float
    offset: float = 0.0
    rate: float = math.inf

    def __post_init__(self) -> None:
        self._set("amplitude", validation.positive("amplitude", self.amplitude))
        self._set("offset", validation.real("offset", self.offset))
        rate = self.rate
        if isinstance(rate, (int, float)) and not isinstance(rate, bool) and rate == math.inf:
            self._set("rate", math.inf)
        else:
            self._set("rate", validation.positive("rate", rate))

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    @property
    def low(self) -> float:
        """Lower end of the bound, ``offset - amplitude``."""
        return self.offset - self.amplitude

    @property
    def high(self) -> float:
        """Upper end of the bound, ``offset + amplitude``."""
        return self.offset + self.amplitude

    @property
    def rate_limited(self) -> bool:
        """Whether a finite rate limit applies."""
        return math.isfinite(self.rate)

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        """The keys of this kind, in the order :func:`format_spec` writes them."""
        return tuple(f.name for f in fields(cls))


@dataclass(frozen=True, kw_only=True)
class UniformSpec(SignalSpec):
    """Uniform bounded white noise on ``[offset - amplitude, offset + amplitude]``: the paper's input."""

    kind: ClassVar[str] = "uniform"


@dataclass(frozen=True, kw_only=True)
class PRBSSpec(SignalSpec):
    """A maximum-length binary sequence between ``offset - amplitude`` and ``offset + amplitude``.

    Parameters
    ----------
    hold : int
        Samples per bit, ``>= 1``: a servo that cannot follow the sample rate
        needs a few.
    order : int
        Register length in bits, 2 to 20; the sequence repeats every
        ``2^order - 1`` bits. The seed picks where in the sequence it starts.
    """

    kind: ClassVar[str] = "prbs"

    hold: int = 1
    order: int = 10

    def __post_init__(self) -> None:
        super().__post_init__()
        self._set("hold", _hold("hold", self.hold))
        order = validation.integer("order", self.order, minimum=2)
        if order > MAX_PRBS_ORDER:
            raise ConfigError(f"order (={order}) must be <= {MAX_PRBS_ORDER}")
        self._set("order", order)

    @property
    def period_bits(self) -> int:
        """Length ``2^order - 1`` of one period of the sequence, in bits."""
        return (1 << self.order) - 1


@dataclass(frozen=True, kw_only=True)
class StepsSpec(SignalSpec):
    """Random steps held for ``hold`` samples each.

    Parameters
    ----------
    hold : int
        Samples per step, ``>= 1``.
    levels : int
        0 for any value in the bound (uniform), else the number (``>= 2``) of
        evenly spaced levels from ``offset - amplitude`` to ``offset + amplitude``.
    """

    kind: ClassVar[str] = "steps"

    hold: int = 5
    levels: int = 0

    def __post_init__(self) -> None:
        super().__post_init__()
        self._set("hold", _hold("hold", self.hold))
        levels = validation.integer("levels", self.levels, minimum=0)
        if levels > MAX_LEVELS:
            raise ConfigError(f"levels (={levels}) must be <= {MAX_LEVELS} (servoid's limit on an excitation's levels)")
        if levels == 1:
            raise ConfigError("levels (=1) must be 0 (any value) or >= 2: one level is a constant")
        self._set("levels", levels)


@dataclass(frozen=True, kw_only=True)
class MultisineSpec(SignalSpec):
    """A periodic sum of equal-amplitude cosines with Schroeder phases (low crest factor).

    Parameters
    ----------
    bands : tuple of (low, high)
        Frequency bands in cycles per sample, ``0 < low < high <= 0.5``; every
        harmonic of ``1/period`` inside a band is excited.
    period : int
        Samples per period, 4 to 2^20; the frequency resolution is ``1/period``.

    Notes
    -----
    The sum is scaled so that its peak over one period is exactly
    ``amplitude``.
    """

    kind: ClassVar[str] = "multisine"

    bands: tuple[tuple[float, float], ...] = ((0.01, 0.25),)
    period: int = 1000

    def __post_init__(self) -> None:
        super().__post_init__()
        period = validation.integer("period", self.period, minimum=4)
        if period > MAX_MULTISINE_PERIOD:
            raise ConfigError(f"period (={period}) must be <= {MAX_MULTISINE_PERIOD}")
        bands = []
        for band in self.bands:
            try:
                lo, hi = (float(v) for v in band)
            except (TypeError, ValueError):
                raise ConfigError(f"bands entry {band!r} must be a pair (low, high) in cycles per sample") from None
            if not (0.0 < lo < hi <= 0.5):
                raise ConfigError(f"band {lo:g}-{hi:g} must satisfy 0 < low < high <= 0.5 (cycles per sample)")
            bands.append((lo, hi))
        if not bands:
            raise ConfigError("bands is empty: give at least one band low-high in cycles per sample")
        self._set("bands", tuple(bands))
        self._set("period", period)
        if not self.harmonics:
            raise ConfigError(
                f"no harmonic of 1/period (period={period} samples) falls in bands "
                f"{_format_bands(self.bands)}: widen a band or lengthen the period"
            )

    @property
    def harmonics(self) -> tuple[int, ...]:
        """Indices ``l`` of the excited frequencies ``l / period`` (cycles per sample)."""
        lines: set[int] = set()
        for lo, hi in self.bands:
            lines.update(range(max(1, math.ceil(lo * self.period)), math.floor(hi * self.period) + 1))
        return tuple(sorted(line for line in lines if 2 * line <= self.period))


@dataclass(frozen=True, kw_only=True)
class ChirpSpec(SignalSpec):
    """A sine whose frequency sweeps from ``f0`` to ``f1`` every ``period`` samples, phase continuous.

    Parameters
    ----------
    f0, f1 : float
        Start and end frequency in cycles per sample, in ``[0, 0.5]``
        (``> 0`` for a logarithmic sweep).
    period : int
        Samples per sweep, ``>= 2``.
    sweep : {"linear", "log"}
        How the frequency moves from ``f0`` to ``f1``.
    """

    kind: ClassVar[str] = "chirp"

    f0: float = 0.005
    f1: float = 0.25
    period: int = 1000
    sweep: str = "linear"

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("f0", "f1"):
            f = validation.real(name, getattr(self, name))
            if not 0.0 <= f <= 0.5:
                raise ConfigError(f"{name} (={f:g}) must lie in [0, 0.5] cycles per sample")
            self._set(name, f)
        self._set("period", validation.integer("period", self.period, minimum=2))
        if self.sweep not in ("linear", "log"):
            raise ConfigError(f"sweep (={self.sweep!r}) must be 'linear' or 'log'")
        if self.sweep == "log" and min(self.f0, self.f1) <= 0.0:
            raise ConfigError(f"a log sweep needs f0 and f1 > 0 (f0={self.f0:g}, f1={self.f1:g})")


@dataclass(frozen=True, kw_only=True)
class LevelsSpec(SignalSpec):
    """Random visits to several operating levels, with a dither around each (Remark 2).

    Parameters
    ----------
    count : int
        Number of operating levels, ``>= 1``, evenly spaced so that level plus
        dither stays in the bound; each is visited once per cycle of ``count``
        visits, in a random order.
    dwell : int
        Samples spent at a level per visit, ``>= 1``.
    dither : float, optional
        Half-width of the uniform dither around each level, unit of ``u``,
        ``0 <= dither <= amplitude`` (``< amplitude`` when ``count > 1``);
        default ``amplitude / count``.
    hold : int
        Samples per dither value, ``>= 1``.
    """

    kind: ClassVar[str] = "levels"

    count: int = 3
    dwell: int = 500
    dither: float | None = field(default=None, metadata={"default": "amplitude/count"})
    hold: int = 1

    def __post_init__(self) -> None:
        super().__post_init__()
        count = limits.bounded_count("count", self.count, limit=MAX_LEVELS, what="an excitation's levels")
        dither = self.amplitude / count if self.dither is None else validation.non_negative("dither", self.dither)
        if dither > self.amplitude or (count > 1 and dither == self.amplitude):
            raise ConfigError(
                f"dither (={dither:g}) must be < amplitude (={self.amplitude:g}) so that {count} levels fit in the bound"
            )
        self._set("count", count)
        self._set("dwell", validation.integer("dwell", self.dwell, minimum=1))
        self._set("dither", dither)
        self._set("hold", _hold("hold", self.hold))

    @property
    def centres(self) -> tuple[float, ...]:
        """The operating levels, unit of ``u``."""
        if self.count == 1:
            return (self.offset,)
        reach = self.amplitude - float(self.dither or 0.0)
        return tuple(self.offset + reach * (-1.0 + 2.0 * i / (self.count - 1)) for i in range(self.count))


@dataclass(frozen=True, kw_only=True)
class GentleSpec(SignalSpec):
    """Gentle sines: segments of ``cycles`` periods whose peak acceleration stays low (:mod:`~servoid.excitation.gentle`).

    Made for a servo whose encoder sits on the load (the play inside its
    position loop): decelerations gentler than the load's own friction keep
    the load on the trailing flank until the motor reverses, so every
    reversal crosses the whole play.

    Parameters
    ----------
    accel : float, optional
        Highest peak acceleration of a segment, unit of ``u`` per sample
        squared, ``> 0``; default ``amplitude (2 pi 0.01)^2`` (a full-amplitude
        segment at 0.01 cycles per sample). From a physical limit ``A`` in
        unit/s^2 at a sample period ``T``: ``A T^2``.
    spread : float
        Ratio of the highest to the lowest peak acceleration, ``>= 1``.
    cycles : int
        Periods per segment, ``>= 1``.
    smallest : float
        Smallest segment amplitude as a fraction of ``amplitude``, in (0, 1].
    """

    kind: ClassVar[str] = "gentle"

    accel: float | None = field(default=None, metadata={"default": "amplitude*(2pi*0.01)^2"})
    spread: float = 8.0
    cycles: int = 3
    smallest: float = 0.25

    def __post_init__(self) -> None:
        super().__post_init__()
        accel = self.amplitude * (2.0 * math.pi * 0.01) ** 2 if self.accel is None else self.accel
        self._set("accel", validation.positive("accel", accel))
        spread = validation.real("spread", self.spread)
        if spread < 1.0:
            raise ConfigError(f"spread (={spread:g}) must be >= 1 (highest over lowest peak acceleration)")
        self._set("spread", spread)
        self._set("cycles", validation.integer("cycles", self.cycles, minimum=1))
        self._set("smallest", validation.in_unit_interval("smallest", self.smallest, open_high=False))


#: Every kind by name, in the order help texts list them.
KINDS: dict[str, type[SignalSpec]] = {
    cls.kind: cls for cls in (UniformSpec, PRBSSpec, StepsSpec, MultisineSpec, ChirpSpec, LevelsSpec, GentleSpec)
}


def _format_bands(bands: tuple[tuple[float, float], ...]) -> str:
    return "+".join(f"{lo!r}-{hi!r}" for lo, hi in bands)


def _format_value(value: Any) -> str:
    if isinstance(value, tuple):
        return _format_bands(value)
    if isinstance(value, float):
        return "inf" if value == math.inf else repr(value)
    return str(value)


def format_spec(spec: SignalSpec) -> str:
    """The text form of ``spec`` with every key, e.g. ``prbs:amplitude=1.5,offset=0.0,rate=inf,hold=3,order=10``."""
    body = ",".join(f"{key}={_format_value(getattr(spec, key))}" for key in spec.keys())
    return f"{spec.kind}:{body}"


def grammar() -> str:
    """One line per kind with its keys and their defaults: what ``--help`` shows."""
    lines = []
    for kind, cls in KINDS.items():
        keys = []
        for f in fields(cls):
            if f.name in ("amplitude", "offset", "rate"):
                continue
            default = f.metadata.get("default", _format_value(f.default) if f.default is not MISSING else "")
            keys.append(f"{f.name}={default}")
        lines.append(f"  {kind:10s} {', '.join(keys) if keys else '(only the shared keys)'}")
    return "\n".join(lines)


def _kinds_hint() -> str:
    return f"valid kinds: {', '.join(KINDS)} (e.g. prbs:amplitude=1.5,hold=3)"


def _convert(cls: type[SignalSpec], key: str, text: str) -> Any:
    """Turn the text of one value into the type its field declares."""
    if key == "bands":
        if not _BANDS.fullmatch(text):
            raise ConfigError(f"bands (={text!r}) must be low-high in cycles per sample, several joined by '+'")
        return tuple((float(lo), float(hi)) for lo, hi in _BAND.findall(text))
    if key == "sweep":
        return text
    default = next(f.default for f in fields(cls) if f.name == key)
    if isinstance(default, int) and not isinstance(default, bool):
        try:
            return int(text)
        except ValueError:
            raise ConfigError(f"{key} (={text!r}) must be an integer") from None
    try:
        return float(text)
    except ValueError:
        raise ConfigError(f"{key} (={text!r}) must be a number") from None


def parse_spec(text: str) -> SignalSpec:
    """Read a spec written ``kind:key=value,...``.

    Parameters
    ----------
    text : str
        For example ``prbs:amplitude=1.5,hold=3`` or
        ``multisine:amplitude=2,bands=0.01-0.2``.

    Returns
    -------
    SignalSpec
        The validated spec of that kind.

    Raises
    ------
    ConfigError
        One line naming what is wrong, with the valid kinds (for an unknown
        kind) or the valid keys of the kind (for anything else).
    """
    if not isinstance(text, str):
        raise ConfigError(f"an excitation spec must be a string like 'prbs:amplitude=1.5', got {text!r}")
    kind, _, body = text.strip().partition(":")
    kind = kind.strip().lower()
    cls = KINDS.get(kind)
    if cls is None:
        raise ConfigError(f"unknown excitation kind {kind!r} in {text!r}; {_kinds_hint()}")
    keys_hint = f"{kind} keys: {', '.join(cls.keys())}"
    values: dict[str, Any] = {}
    try:
        for item in filter(None, (part.strip() for part in body.split(","))):
            key, eq, value = item.partition("=")
            key = key.strip()
            if not eq or not value.strip():
                raise ConfigError(f"{item!r} must be key=value")
            if key not in cls.keys():
                raise ConfigError(f"unknown key {key!r}")
            if key in values:
                raise ConfigError(f"key {key!r} given twice")
            values[key] = _convert(cls, key, value.strip())
        if "amplitude" not in values:
            raise ConfigError("amplitude is required (half-width of the bound around offset, unit of u)")
        return cls(**values)
    except ConfigError as exc:
        raise ConfigError(f"bad excitation spec {text!r}: {exc}; {keys_hint}") from None
