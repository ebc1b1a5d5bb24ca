"""Argument checks that name the value and what was expected.

A leaf module like :mod:`servoid.errors`: the pillars use it to validate at
their boundaries, so that bad input fails with ``"c1 (=-0.2) must be > 0"``
instead of a traceback from deep inside NumPy or, worse, a silent wrong answer.
"""

from __future__ import annotations

import math
import numbers
import sys
from typing import TYPE_CHECKING, Any

from servoid.errors import ConfigError
from servoid.limits import digits_of

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

# NumPy is imported only by the checks that build arrays: the command line's
# parsers use the scalar checks, and must start without loading NumPy. NumPy
# registers its scalar types with the ``numbers`` ABCs, so the scalar checks
# accept them without naming them.

__all__ = [
    "real",
    "positive",
    "non_negative",
    "integer",
    "in_unit_interval",
    "signal",
    "show",
    "reject_unknown",
]


def show(value: Any) -> str:
    """``repr`` of a value for a message, without NumPy's type wrappers (``1.5``, not ``np.float64(1.5)``)."""
    numpy = sys.modules.get("numpy")  # a NumPy scalar exists only once NumPy is loaded
    if numpy is not None and isinstance(value, numpy.generic):
        value = value.item()
    return repr(value)


def real(name: str, value: Any) -> float:
    """Return ``value`` as a finite float, or raise :class:`ConfigError` naming it."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(f"{name} (={show(value)}) must be a real number")
    try:
        out = float(value)
    except OverflowError:  # an int beyond a float's range; its repr may run to thousands of digits
        raise ConfigError(f"{name} (an integer of about {digits_of(value)} digits) must be finite") from None
    if not math.isfinite(out):
        raise ConfigError(f"{name} (={show(value)}) must be finite")
    return out


def positive(name: str, value: Any) -> float:
    """Return ``value`` as a float > 0."""
    out = real(name, value)
    if out <= 0.0:
        raise ConfigError(f"{name} (={show(value)}) must be > 0")
    return out


def non_negative(name: str, value: Any) -> float:
    """Return ``value`` as a float >= 0."""
    out = real(name, value)
    if out < 0.0:
        raise ConfigError(f"{name} (={show(value)}) must be >= 0")
    return out


def in_unit_interval(name: str, value: Any, *, open_low: bool = True, open_high: bool = True) -> float:
    """Return ``value`` as a float in (0, 1), with the ends included on request."""
    out = real(name, value)
    lo_ok = out > 0.0 if open_low else out >= 0.0
    hi_ok = out < 1.0 if open_high else out <= 1.0
    if not (lo_ok and hi_ok):
        lo = "(" if open_low else "["
        hi = ")" if open_high else "]"
        raise ConfigError(f"{name} (={show(value)}) must lie in {lo}0, 1{hi}")
    return out


def integer(name: str, value: Any, *, minimum: int | None = None) -> int:
    """Return ``value`` as an int (bools rejected), optionally ``>= minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        if isinstance(value, numbers.Real) and float(value).is_integer():
            value = int(float(value))
        else:
            raise ConfigError(f"{name} (={show(value)}) must be an integer")
    out = int(value)
    if minimum is not None and out < minimum:
        raise ConfigError(f"{name} (={show(value)}) must be >= {minimum}")
    return out


def signal(name: str, values: Any, *, min_length: int = 1) -> np.ndarray:
    """Return ``values`` as a 1-D float64 array of finite numbers.

    Raises
    ------
    ConfigError
        If ``values`` is not 1-D numeric, is shorter than ``min_length``, or
        holds NaN or infinity (the message gives the first bad index).
    """
    import numpy as np

    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name} must be a sequence of numbers ({exc})") from exc
    if arr.ndim != 1:
        raise ConfigError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if arr.size < min_length:
        raise ConfigError(f"{name} has {arr.size} samples, at least {min_length} are needed")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ConfigError(f"{name}[{i}] (={float(arr[i])!r}) is not finite; {int(bad.sum())} non-finite values in all")
    return arr


def reject_unknown(what: str, given: Any, allowed: Any) -> None:
    """Raise :class:`ConfigError` if ``given`` has keys not in ``allowed``, naming them."""
    unknown = sorted(set(given) - set(allowed))
    if unknown:
        raise ConfigError(f"unknown {what} {', '.join(map(repr, unknown))}; valid: {', '.join(sorted(allowed))}")
