"""Turning named arrays into a recording: the checks every reader shares, with one message for each failure.

The checks of values (finite, within :data:`servoid.limits.MAX_MAGNITUDE`) and of time are
:mod:`servoid.recording`'s, which the CSV reader runs too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from servoid import limits
from servoid.errors import DataError
from servoid.recording import Recording, check_magnitudes, check_time, time_scale

__all__ = ["series", "assemble", "listing"]


def series(values: Any, *, what: str) -> np.ndarray:
    """``values`` as a 1-D float64 array of finite numbers.

    Parameters
    ----------
    values : array-like
        A vector (a column or row matrix is flattened).
    what : str
        Names the values in the messages (``"variable 'qm' of x.mat"``).

    Raises
    ------
    DataError
        Not numeric (text, true/false, complex numbers, an integer beyond a
        float's range), a matrix, empty, or with a NaN or infinity (the first
        one's index named).
    """
    if isinstance(values, (list, tuple)):  # JSON's true and false would pass as 1 and 0
        for k, value in enumerate(values):
            if isinstance(value, (bool, np.bool_)):
                raise DataError(f"{what}: sample {k} (={value!r}) is not a number")
    try:
        raw = np.asarray(values)
        kind = raw.dtype.kind
        arr = raw.astype(np.float64) if kind not in "cb" else raw
    except (TypeError, ValueError, OverflowError):
        if isinstance(values, (list, tuple)):
            for k, value in enumerate(values):
                try:
                    float(value)
                except OverflowError:  # an integer beyond a float's range (JSON has no limit on digits)
                    raise DataError(f"{what}: sample {k} (an integer of about {limits.digits_of(value)} digits) "
                                    f"lies beyond +/-{limits.MAX_MAGNITUDE:g}") from None  # fmt: skip
                except (TypeError, ValueError):
                    raise DataError(f"{what}: sample {k} (={value!r}) is not a number") from None
        raise DataError(f"{what} is not numeric (a {type(values).__name__})") from None
    if kind == "c":  # NumPy would drop the imaginary parts with a mere warning
        raise DataError(f"{what} holds complex numbers; expected real ones")
    if kind == "b":
        raise DataError(f"{what} holds true/false values; expected numbers")
    if sum(n > 1 for n in arr.shape) > 1:
        shape = "x".join(map(str, arr.shape))
        raise DataError(f"{what} is a {shape} matrix; expected a vector (one value per sample)")
    arr = arr.ravel()
    if arr.size == 0:
        raise DataError(f"{what} is empty")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        k = int(bad[0])
        raise DataError(f"{what}: sample {k} (={float(arr[k])!r}) is not finite; {bad.size} non-finite values in all")
    return arr


def assemble(
    arrays: Mapping[str, np.ndarray],
    *,
    names: Mapping[str, str],
    where: str,
    time_unit: str | None,
    metadata: Mapping[str, str],
    path: str,
    notes: tuple[str, ...] = (),
) -> Recording:
    """A :class:`~servoid.recording.Recording` from ``u``, ``y`` and optionally ``t``, checked.

    Parameters
    ----------
    arrays : mapping
        ``u``, ``y`` and optionally ``t`` (in ``time_unit``), each from :func:`series`.
    names : mapping
        The source's name of each array, for the messages.
    where : str
        The source (a path), for the messages.
    time_unit : str, optional
        Unit of ``t`` (default seconds); ``t`` is returned in seconds.
    metadata : mapping
        Kept as the recording's metadata.
    path : str
        Kept as the recording's path.
    notes : tuple of str
        The reader's own notes, kept first.

    Raises
    ------
    DataError
        Arrays of different lengths (each named with its length), a value
        beyond :data:`~servoid.limits.MAX_MAGNITUDE`, or time that does not
        increase strictly.
    """
    lengths = {names[k]: a.size for k, a in arrays.items()}
    if len(set(lengths.values())) > 1:
        shown = ", ".join(f"{name} {n}" for name, n in lengths.items())
        raise DataError(f"{where}: the series differ in length ({shown}); they must hold one value per sample each")
    check_magnitudes({names[k]: a for k, a in arrays.items()}, where=where)
    t = arrays.get("t")
    found = list(notes)
    if t is not None:
        t = t * time_scale(time_unit or "s")
        found += check_time(t, where=where, column=names["t"], unit_given=time_unit is not None)
    return Recording(u=arrays["u"], y=arrays["y"], t=t, metadata=dict(metadata), path=path, notes=tuple(found))


def listing(shapes: Mapping[str, str]) -> str:
    """``name (shape), ...`` for a message that lists what a file holds."""
    return ", ".join(f"{name} ({shape})" if shape else name for name, shape in shapes.items()) or "nothing"
