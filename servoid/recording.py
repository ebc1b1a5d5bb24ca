"""Recordings on disk: CSV with a header row, written as samples arrive.

Format
------
UTF-8 text. Optional metadata lines first, each ``# key: value``; then one
header row of column names; then one row per sample. The columns servoid
reads are ``u`` (input) and ``y`` (measured output), with ``t`` (time in
seconds) when known, and ``status`` when the recording comes from a live
session (``ok``, ``late``, ``missed``, ``timeout``: see :mod:`servoid.session`);
in such a recording ``y`` is ``nan`` where nothing was measured. Other
columns are kept by the writer and ignored by :func:`read_recording`. Units
are given in the metadata (``# unit: rad``).

:class:`RecordingWriter` appends and flushes each row as it is written, so a
crash, a kill or Ctrl-C leaves every sample measured so far in a readable file
(at worst the last line is cut short, which :func:`read_recording` drops with
a note rather than failing).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from servoid.errors import DataError
from servoid.files import read_text

__all__ = ["Recording", "read_recording", "write_recording", "RecordingWriter", "split_metadata"]


@dataclass(frozen=True)
class Recording:
    """A record read from disk.

    Attributes
    ----------
    u, y : ndarray
        Input and measured output.
    t : ndarray or None
        Time of each sample in seconds, when the file has a ``t`` column.
    metadata : dict
        The ``# key: value`` lines of the file.
    path : str
        Where it was read from.
    notes : tuple of str
        Things the reader fixed up (a truncated last line).
    status : ndarray of str or None
        Per-sample status of a live recording (its ``y`` is NaN where nothing
        was measured), None for other recordings.
    """

    u: np.ndarray
    y: np.ndarray
    t: np.ndarray | None
    metadata: dict[str, str] = field(default_factory=dict)
    path: str = ""
    notes: tuple[str, ...] = ()
    status: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.u.size)

    @property
    def sample_period(self) -> float | None:
        """Median time between samples in seconds, when ``t`` is known."""
        if self.t is None or self.t.size < 2:
            return None
        return float(np.median(np.diff(self.t)))


def split_metadata(lines: list[str]) -> tuple[dict[str, str], list[str]]:
    """The leading ``# key: value`` lines as a dict, and the lines after them."""
    meta: dict[str, str] = {}
    i = 0
    while i < len(lines) and (lines[i].startswith("#") or not lines[i].strip()):
        text = lines[i].lstrip("#").strip()
        if ":" in text:
            key, value = text.split(":", 1)
            meta[key.strip()] = value.strip()
        i += 1
    return meta, lines[i:]


def read_recording(path: str | os.PathLike[str], *, u_column: str = "u", y_column: str = "y") -> Recording:
    """Read a recording CSV.

    Parameters
    ----------
    path : path-like
        The file.
    u_column, y_column : str
        Names of the input and output columns.

    Raises
    ------
    DataError
        Missing or unreadable file, no header, missing columns (the message
        lists those found), a value that is not a number or not finite (with
        its row and column), or no data rows.
    """
    p = Path(path)
    text = read_text(p, what="CSV file")
    lines = text.splitlines()
    meta, body = split_metadata(lines)
    if not body:
        raise DataError(f"{p}: no header row (expected column names such as 't,u,y')")
    first_row = len(lines) - len(body) + 1  # 1-based line number of the header
    reader = csv.reader(io.StringIO("\n".join(body)))
    header = [h.strip() for h in next(reader)]
    wanted = {"u": u_column, "y": y_column}
    missing = [name for name in wanted.values() if name not in header]
    if missing:
        raise DataError(
            f"{p}: missing column(s) {', '.join(map(repr, missing))}; the header has {', '.join(map(repr, header))}"
        )
    cols = {key: header.index(name) for key, name in wanted.items()}
    if "t" in header:
        cols["t"] = header.index("t")
    status_col = header.index("status") if "status" in header else None
    # a live recording marks unmeasured samples by their status and a nan y
    may_be_nan = {"y"} if status_col is not None else set()
    rows = [r for r in reader if r and any(c.strip() for c in r)]
    notes: list[str] = []
    if rows and not text.endswith("\n"):
        # The writer ends every row with a newline: a last line without one was
        # cut off mid-write (crash, kill). Keep it only if it parses whole.
        try:
            _parse_row(rows[-1], header, cols, p, first_row + len(rows), may_be_nan)
        except DataError:
            rows.pop()
            notes.append("dropped a truncated last line (the recording was cut off while writing)")
    if not rows:
        raise DataError(f"{p}: the header is there but no data rows follow")
    data = {key: np.empty(len(rows)) for key in cols}
    for i, row in enumerate(rows):
        for key, value in _parse_row(row, header, cols, p, first_row + 1 + i, may_be_nan).items():
            data[key][i] = value
    status = None if status_col is None else np.array([r[status_col].strip() for r in rows])
    return Recording(
        u=data["u"], y=data["y"], t=data.get("t"), metadata=meta, path=str(p), notes=tuple(notes), status=status
    )


def _parse_row(
    row: list[str],
    header: list[str],
    cols: dict[str, int],
    p: Path,
    line_no: int,
    may_be_nan: frozenset[str] | set[str] = frozenset(),
) -> dict[str, float]:
    if len(row) != len(header):
        raise DataError(f"{p}, line {line_no}: {len(row)} fields, the header has {len(header)}")
    out = {}
    for key, j in cols.items():
        cell = row[j].strip()
        try:
            value = float(cell)
        except ValueError:
            raise DataError(f"{p}, line {line_no}, column {header[j]!r}: {cell!r} is not a number") from None
        if not math.isfinite(value) and not (key in may_be_nan and math.isnan(value)):
            raise DataError(f"{p}, line {line_no}, column {header[j]!r}: {cell!r} is not finite")
        out[key] = value
    return out


def _format(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return str(value)


class RecordingWriter:
    """Write a recording row by row, flushing each row to the operating system.

    Parameters
    ----------
    path : path-like
        File to create (parent directories are created).
    columns : sequence of str
        Column names, written as the header row.
    metadata : mapping, optional
        Written first as ``# key: value`` lines.
    fsync_every : int
        Also ``fsync`` every this many rows (0: never); flushing alone already
        survives a crash or kill of the process, fsync also a power cut.

    Notes
    -----
    Use as a context manager; :meth:`close` is idempotent.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        columns: Sequence[str],
        *,
        metadata: Mapping[str, Any] | None = None,
        fsync_every: int = 0,
    ) -> None:
        self.path = Path(path)
        self.columns = tuple(columns)
        self.rows = 0
        self._fsync_every = fsync_every
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh: IO[str] | None = open(self.path, "w", encoding="utf-8", newline="")
        for key, value in (metadata or {}).items():
            self._fh.write(f"# {key}: {value}\n")
        self._fh.write(",".join(self.columns) + "\n")
        self._fh.flush()

    def append(self, *values: Any) -> None:
        """Write one row (one value per column, in order) and flush it."""
        if self._fh is None:
            raise DataError(f"{self.path}: the recording is closed")
        if len(values) != len(self.columns):
            raise DataError(f"a row needs {len(self.columns)} values ({', '.join(self.columns)}), got {len(values)}")
        self._fh.write(",".join(_format(v) for v in values) + "\n")
        self._fh.flush()
        self.rows += 1
        if self._fsync_every and self.rows % self._fsync_every == 0:
            os.fsync(self._fh.fileno())

    def close(self) -> None:
        """Flush, sync and close; safe to call more than once."""
        if self._fh is not None:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()
            self._fh = None

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_recording(
    path: str | os.PathLike[str],
    columns: Mapping[str, Sequence[float] | np.ndarray],
    *,
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Write whole columns at once (same format as :class:`RecordingWriter`)."""
    arrays = {name: np.asarray(values) for name, values in columns.items()}
    lengths = {a.size for a in arrays.values()}
    if len(lengths) > 1:
        raise DataError(f"columns differ in length: { {k: v.size for k, v in arrays.items()} }")
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with open(p, "w", encoding="utf-8", newline="") as fh:
        for key, value in (metadata or {}).items():
            fh.write(f"# {key}: {value}\n")
        fh.write(",".join(arrays) + "\n")
        stacked = np.column_stack([a.astype(np.float64) for a in arrays.values()])
        np.savetxt(fh, stacked, delimiter=",", fmt="%.17g")
    return p
