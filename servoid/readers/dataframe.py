"""pandas DataFrames: a recording from named columns of a table already in Python (a notebook, a script).

pandas is not imported: the frame's own methods are used, so any object
with ``columns`` and ``[name]`` that gives arrays works (a pandas or a
Polars-like frame). Install pandas with ``pip install 'servoid[notebook]'``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from servoid.errors import DataError
from servoid.readers._series import assemble, listing, series
from servoid.recording import NO_TIME, Recording

__all__ = ["from_dataframe", "INDEX"]

#: ``t=INDEX`` takes the time from the frame's index (numbers, datetimes or timedeltas).
INDEX = "index"


def from_dataframe(
    frame: Any,
    *,
    u: str = "u",
    y: str = "y",
    t: str | None | Literal[False] = None,
    time_unit: str | None = None,
    metadata: Mapping[str, str] | None = None,
) -> Recording:
    """A recording from columns of a DataFrame.

    Parameters
    ----------
    frame : DataFrame
        The table, one row per sample.
    u, y : str
        Columns of the input and the measured output.
    t : str, None or False
        Column of the time; ``"index"`` for the frame's index (a
        ``DatetimeIndex`` or ``TimedeltaIndex`` is read in seconds from its
        first entry); None reads a column ``t`` when there is one; False no time.
    time_unit : str, optional
        Unit of a numeric time column or index (``s``, ``ms``, ``us``, ``ns``;
        default seconds).
    metadata : mapping, optional
        Kept as the recording's metadata (``{"unit": "rad"}``).

    Raises
    ------
    DataError
        Not a table, a column missing (the message lists those there) or
        named twice, values that are not finite numbers, time that does not
        increase strictly.
    """
    columns = getattr(frame, "columns", None)
    if columns is None:
        raise DataError(f"expected a DataFrame, got a {type(frame).__name__}")
    have = [str(c) for c in columns]
    wanted = {"u": u, "y": y}
    if t is None:
        if "t" in have:
            wanted["t"] = "t"
    elif t is not NO_TIME:
        wanted["t"] = str(t)
    arrays = {}
    unit = time_unit
    for role, name in wanted.items():
        if role == "t" and name == INDEX and INDEX not in have:
            arrays[role], in_seconds = _index_time(frame.index)
            unit = "s" if in_seconds else time_unit
            continue
        count = have.count(name)
        if count != 1:
            there = listing({c: "" for c in have})
            problem = "no column" if count == 0 else f"{count} columns named"
            raise DataError(f"the DataFrame has {problem} {name!r}; its columns: {there}")
        arrays[role] = series(_values(frame[name]), what=f"column {name!r}")
    meta = {"source": "DataFrame", "u": u, "y": y, **(metadata or {})}
    return assemble(arrays, names=wanted, where="DataFrame", time_unit=unit, metadata=meta, path="")


def _values(column: Any) -> Any:
    return column.to_numpy() if hasattr(column, "to_numpy") else np.asarray(column)


def _index_time(index: Any) -> tuple[np.ndarray, bool]:
    """The index as numbers, and whether they are seconds already (a datetime or timedelta index)."""
    values = np.asarray(index)
    if values.dtype.kind in "mM":
        # seconds from the first entry; nanoseconds as integers first, so that a date's epoch offset costs no precision
        ns = (values - values[0]).astype("timedelta64[ns]").astype(np.int64)
        return series(ns * 1e-9, what="the index"), True
    return series(values, what="the index"), False
