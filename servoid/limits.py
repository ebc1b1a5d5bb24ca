"""How big an input may be: every size limit servoid enforces, and the checks that name the value and the limit.

Each limit bounds the memory or the time of a run *before* the work starts,
so that a typing slip (``--samples 10000000000``, ``count=1e9``, a model
with 20 000 coefficients, a delay of 1e9 samples) ends in one line naming
the value and the limit, never in a machine swapping itself to death or a
run that never finishes. Every limit sits far beyond what a bench needs,
and says why it is where it is.

A leaf module like :mod:`servoid.validation`: the pillars use it at their
boundaries (the excitation's levels, the model's orders).
"""

from __future__ import annotations

import math
import numbers
import re
from typing import TYPE_CHECKING, Any

from servoid.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

# NumPy is imported only by the check of arrays (:func:`magnitudes`): the command line checks its
# arguments with the scalar checks and must start without loading NumPy. NumPy registers its scalar
# types with the ``numbers`` ABCs, so the scalar checks accept them without naming them.

__all__ = [
    "MAX_SAMPLES",
    "MAX_ORDER",
    "MAX_DELAY",
    "MAX_DURATION_S",
    "MAX_LEVELS",
    "MAX_TEXT_CHARS",
    "MAX_JSON_DEPTH",
    "MAX_JSON_BYTES",
    "MAX_MAGNITUDE",
    "MAX_SEED",
    "bounded_count",
    "bounded_real",
    "orders",
    "seed",
    "text",
    "magnitudes",
    "lone_surrogate",
    "digits_of",
]

#: Samples of one record (simulated, live or read): 10 million samples are 2.8 hours at 1 kHz,
#: and the pipeline's arrays for them take about 2 GB; ``servoid monitor``, which keeps no
#: samples, is bounded by :data:`MAX_DURATION_S` instead.
MAX_SAMPLES = 10_000_000

#: Orders of the linear block (``na``, and the ``nb + 1`` numerator coefficients): a servo's
#: position loop needs 1 to 4; the stability check and the refinement grow with the cube of it.
MAX_ORDER = 64

#: Input delay, samples: 10 s at 1 kHz. Simulation, feedforward preview and the regressor all
#: hold a buffer this long.
MAX_DELAY = 10_000

#: Duration of one ``servoid monitor`` run, seconds: 115 days (the clock arithmetic stays exact).
MAX_DURATION_S = 1e7

#: Levels of an excitation (``levels:count=``, ``steps:levels=``): each level is visited in turn,
#: and more levels than samples of a run would never all be visited.
MAX_LEVELS = 100_000

#: Characters of one text value (a unit, a name, a string in a model file): PATH_MAX on Linux.
MAX_TEXT_CHARS = 4096

#: Nesting depth of a JSON file servoid reads (a model file nests 3 deep; ``servo`` identities a
#: few more); Python's own parser gives up near 1000 with a RecursionError.
MAX_JSON_DEPTH = 32

#: Size of a JSON file servoid reads (a model file is a few kB).
MAX_JSON_BYTES = 4 << 20

#: Largest magnitude of any number servoid computes with (positions, parameters, inputs):
#: squares and sums of a record's squares stay finite (1e200 * 1e7 < 1e308), and no bench
#: measures anything near it.
MAX_MAGNITUDE = 1e100

#: Largest seed: what NumPy's generators take in one 64-bit word.
MAX_SEED = 2**64 - 1

_SURROGATE = re.compile("[\ud800-\udfff]")


def _integer(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        if isinstance(value, numbers.Real) and math.isfinite(value) and float(value).is_integer():
            return int(float(value))
        raise ConfigError(f"{name} (={value!r}) must be an integer")
    return int(value)


def digits_of(value: Any) -> int:
    """About how many decimal digits the integer ``value`` has (its ``str`` may be refused: over 4300 digits).

    Parameters
    ----------
    value : int
        The integer.
    """
    return int(int(value).bit_length() * 0.30103) + 1


def bounded_count(name: str, value: Any, *, limit: int, minimum: int = 1, what: str = "") -> int:
    """``value`` as an int in ``[minimum, limit]``, or a :class:`ConfigError` naming it and the limit.

    Parameters
    ----------
    name : str
        The value's name in the message (``--samples``, ``count``).
    value : int
        The value.
    limit : int
        The largest value allowed (one of this module's limits).
    minimum : int
        The smallest value allowed.
    what : str
        What the limit is, for the message (``"a record's length"``).
    """
    number = _integer(name, value)
    if number < minimum:
        raise ConfigError(f"{name} (={number}) must be >= {minimum}")
    if number > limit:
        why = f" (servoid's limit on {what})" if what else " (servoid's limit)"
        raise ConfigError(f"{name} (={number}) must be <= {limit}{why}")
    return number


def bounded_real(name: str, value: Any, *, limit: float = MAX_MAGNITUDE) -> float:
    """``value`` as a finite float with ``|value| <= limit``, or a :class:`ConfigError` naming it.

    Parameters
    ----------
    name : str
        The value's name in the message.
    value : float
        The value.
    limit : float
        Largest magnitude allowed (default :data:`MAX_MAGNITUDE`).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(f"{name} (={value!r}) must be a real number")
    try:
        number = float(value)
    except OverflowError:  # an int too large for a float
        raise ConfigError(f"{name} (an integer of about {digits_of(value)} digits) must lie within "
                          f"+/-{limit:g}") from None  # fmt: skip
    if not math.isfinite(number):
        raise ConfigError(f"{name} (={number!r}) must be finite")
    if abs(number) > limit:
        raise ConfigError(f"{name} (={number!r}) must lie within +/-{limit:g} (servoid's limit on any number)")
    return number


def orders(na: Any, nb: Any, delay: Any, *, prefix: str = "") -> None:
    """The model's orders and delay within :data:`MAX_ORDER` and :data:`MAX_DELAY` (``na >= 1``, ``nb >= 0``, ``d >= 1``).

    Parameters
    ----------
    na, nb, delay : int
        The orders of the linear block and its input delay in samples.
    prefix : str
        Put before each name in the messages (``"--"`` on the command line).
    """
    what = "the order of the linear block"
    bounded_count(f"{prefix}na", na, limit=MAX_ORDER, what=what)
    bounded_count(f"{prefix}nb", nb, minimum=0, limit=MAX_ORDER - 1, what=what)
    bounded_count(f"{prefix}delay", delay, limit=MAX_DELAY, what="the delay in samples")


def seed(name: str, value: Any) -> int:
    """``value`` as a seed for NumPy's generators: an int in ``[0, MAX_SEED]``.

    Parameters
    ----------
    name : str
        The value's name in the message (``--seed``).
    value : int
        The seed.
    """
    number = _integer(name, value)
    if not 0 <= number <= MAX_SEED:
        raise ConfigError(f"{name} (={number}) must lie in 0 .. 2**64 - 1 (a seed is a non-negative integer)")
    return number


def lone_surrogate(value: str) -> int | None:
    """Index of the first lone surrogate in ``value`` (text that is not valid Unicode), else None.

    Python hands undecodable bytes of the command line and ``\\ud800``-style
    escapes of JSON through as lone surrogates, which no UTF-8 file or
    terminal can take.

    Parameters
    ----------
    value : str
        The text.
    """
    found = _SURROGATE.search(value)
    return None if found is None else found.start()


def text(name: str, value: Any, *, limit: int = MAX_TEXT_CHARS) -> str:
    """``value`` as text that any file or terminal takes: a str, valid Unicode, at most ``limit`` characters.

    Parameters
    ----------
    name : str
        The value's name in the message (``--unit``, ``units.output``).
    value : str
        The text.
    limit : int
        Most characters allowed (default :data:`MAX_TEXT_CHARS`).
    """
    if not isinstance(value, str):
        raise ConfigError(f"{name} (={value!r}) must be text")
    where = lone_surrogate(value)
    if where is not None:
        # repr() shows the surrogate as an escape (\udcff), which every terminal can print
        raise ConfigError(f"{name} (={value[:80]!r}) is not valid Unicode text (a lone surrogate at character {where})")
    if len(value) > limit:
        raise ConfigError(f"{name} ({len(value)} characters) must be at most {limit} characters long")
    return value


def magnitudes(name: str, values: np.ndarray, *, limit: float = MAX_MAGNITUDE) -> None:
    """Raise :class:`ConfigError` naming the first element of ``values`` beyond ``+/-limit`` (NaN passes).

    Parameters
    ----------
    name : str
        The array's name in the message (``y``).
    values : ndarray
        The values (float).
    limit : float
        Largest magnitude allowed (default :data:`MAX_MAGNITUDE`).
    """
    import numpy as np

    with np.errstate(invalid="ignore"):
        beyond = np.abs(values) > limit
    if beyond.any():
        i = int(np.flatnonzero(beyond)[0])
        raise ConfigError(
            f"{name}[{i}] (={float(values[i])!r}) lies beyond +/-{limit:g} (servoid's limit on any number); "
            f"{int(beyond.sum())} such values in all: is the column's unit right?"
        )
