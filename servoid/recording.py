"""Recordings on disk: servoid's CSV format, written as samples arrive and read back checked.

Format
------
UTF-8 text. Optional metadata lines first, each ``# key: value``; then one
header row of column names; then one row per sample. The columns servoid
reads are ``u`` (input) and ``y`` (measured output), with ``t`` (time, in
seconds unless ``# time_unit: ms`` or the reader says otherwise) when known,
and ``status`` when the recording comes from a live session (``ok``,
``late``, ``missed``, ``timeout``: see :mod:`servoid.session`); in such a
recording ``y`` is ``nan`` where nothing was measured. Other columns are kept
by the writer and ignored by :func:`read_recording`, which can also take the
input, output and time from columns of other names (a CSV from another
tool). Units are given in the metadata (``# unit: rad``).

Every value must lie within :data:`servoid.limits.MAX_MAGNITUDE` (``1e100``):
``-1e300`` is finite yet no position a bench measures (a wrong unit, a
corrupted line), and its square is not finite.

Time must increase strictly from row to row: a repeated stamp, or one that
goes back (rows reversed or shuffled), is refused with its line, because a
model in samples is only as good as the order of its samples; a file whose
time column is wrong can be read without it (``time_column=NO_TIME``), the
rows then taken as equally spaced samples in file order.

:class:`RecordingWriter` appends and flushes each row as it is written, so a
crash, a kill or Ctrl-C leaves every sample measured so far in a readable file
(at worst the last line is cut short, which :func:`read_recording` drops with
a note rather than failing). The other formats servoid reads (MATLAB files,
ROS 2 bags, DataFrames, BAM logs) are in :mod:`servoid.readers`.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from servoid import limits, validation
from servoid.errors import ConfigError, DataError
from servoid.files import read_text

__all__ = [
    "Recording",
    "read_recording",
    "read_column",
    "check_time",
    "check_magnitudes",
    "time_scale",
    "periods_differ",
    "TIME_UNITS",
    "NO_TIME",
    "write_recording",
    "RecordingWriter",
    "split_metadata",
]


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

    def with_metadata(self, metadata: Mapping[str, str]) -> Recording:
        """The same samples with ``metadata`` added to (and overriding) the recording's own."""
        return dataclasses.replace(self, metadata={**self.metadata, **metadata})

    def decimated(self, factor: int) -> Recording:
        """Every ``factor``-th sample, starting with the first.

        No anti-alias filter: a filter would add a phase lag to ``y`` that the
        model would then have to explain; decimate smooth records only.

        Parameters
        ----------
        factor : int
            Keep one sample in ``factor`` (>= 1).
        """
        factor = validation.integer("factor", factor, minimum=1)
        if factor == 1:
            return self
        sl = slice(None, None, factor)
        return dataclasses.replace(self, **self._sliced(sl), metadata={**self.metadata, "decimated_by": str(factor)})

    def split(self, fraction: float = 0.5) -> tuple[Recording, Recording]:
        """Cut in two at ``fraction`` of the length: training first, validation second.

        Parameters
        ----------
        fraction : float
            Share of the samples in the first part, in (0, 1).
        """
        frac = validation.in_unit_interval("fraction", fraction)
        k = int(round(frac * len(self)))
        if k < 1 or k >= len(self):
            raise ConfigError(f"fraction (={fraction}) leaves one part of {len(self)} samples empty")
        first = dataclasses.replace(
            self, **self._sliced(slice(0, k)), metadata={**self.metadata, "part": f"first {frac:.0%}"}
        )
        second = dataclasses.replace(
            self, **self._sliced(slice(k, None)), metadata={**self.metadata, "part": f"second {1 - frac:.0%}"}
        )
        return first, second

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write as a servoid recording CSV (``t`` when known, ``u``, ``y``; metadata as ``#`` lines).

        Parameters
        ----------
        path : path-like
            The file to write (parent folders are created).
        """
        cols: dict[str, np.ndarray] = {}
        if self.t is not None:
            cols["t"] = self.t
        cols["u"] = self.u
        cols["y"] = self.y
        return write_recording(path, cols, metadata=self.metadata)

    def _sliced(self, sl: slice) -> dict[str, Any]:
        return {
            "u": self.u[sl],
            "y": self.y[sl],
            "t": None if self.t is None else self.t[sl],
            "status": None if self.status is None else self.status[sl],
        }


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


#: Units a time column may be in, and seconds per unit.
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}

#: ``time_column`` value that reads no time at all: the rows are samples in file order, equally spaced.
NO_TIME = False

#: A median sample period above this many seconds suggests a time column in another unit.
_SLOW_PERIOD_S = 1.0

#: Sample intervals longer than this many median periods are reported as gaps.
_GAP_FACTOR = 2.0


def periods_differ(a: float | None, b: float | None) -> bool:
    """Whether two sample periods (seconds, None when unknown) differ by more than 2 %: a model in samples made at one does not carry over to the other.

    Parameters
    ----------
    a, b : float or None
        The periods; an unknown one differs from nothing.
    """
    return a is not None and b is not None and abs(a - b) > 0.02 * max(a, b)


def time_scale(unit: str) -> float:
    """Seconds per ``unit`` (``s``, ``ms``, ``us``, ``ns``).

    Raises
    ------
    ConfigError
        Naming the unit and the known ones.
    """
    try:
        return TIME_UNITS[unit]
    except (KeyError, TypeError):
        raise ConfigError(f"time unit {unit!r} is not one of {', '.join(TIME_UNITS)}") from None


def read_recording(
    path: str | os.PathLike[str],
    *,
    u_column: str = "u",
    y_column: str = "y",
    time_column: str | None | Literal[False] = None,
    time_unit: str | None = None,
) -> Recording:
    """Read a recording CSV.

    Parameters
    ----------
    path : path-like
        The file.
    u_column, y_column : str
        Names of the input and output columns.
    time_column : str, None or False
        Name of the time column; None reads ``t`` when the header has it;
        False (:data:`NO_TIME`) reads no time: the rows are taken as equally
        spaced samples in file order.
    time_unit : str, optional
        Unit of the time column: ``s``, ``ms``, ``us`` or ``ns`` (:data:`TIME_UNITS`);
        default the file's ``# time_unit:`` line, else seconds. Times are
        returned in seconds.

    Returns
    -------
    Recording
        With notes for what the reader fixed up or found odd: a truncated
        last line dropped, gaps in time, a sample period so long that the
        time column is probably not in seconds.

    Raises
    ------
    DataError
        Missing or unreadable file, no header, a column asked for that is
        missing (the message lists those found) or named twice in the
        header, a field longer than the CSV reader's limit, a value that is
        not a number or not finite (with its line and column) or beyond
        :data:`~servoid.limits.MAX_MAGNITUDE` (:func:`check_magnitudes`), time
        that does not increase strictly (with the line), or no data rows.
    ConfigError
        An unknown time unit.
    """
    table = _read_table(path)
    unit = time_unit if time_unit is not None else table.meta.get("time_unit", "s")
    scale = time_scale(unit)
    wanted = {"u": u_column, "y": y_column}
    if time_column is None:
        if "t" in table.header:
            wanted["t"] = "t"
    elif time_column is not NO_TIME:
        wanted["t"] = str(time_column)
    if "status" in table.header:
        wanted["status"] = "status"
    cols = table.locate(wanted)
    status_col = cols.pop("status", None)
    # a live recording marks unmeasured samples by their status and a nan y
    data, notes = table.numbers(cols, may_be_nan={"y"} if status_col is not None else set())
    check_magnitudes({wanted[key]: values for key, values in data.items()}, where=f"{table.path}")
    t = data.get("t")
    if t is not None:
        t = t * scale if scale != 1.0 else t
        notes += check_time(t, where=f"{table.path}", first_line=table.first_row + 1, column=wanted["t"],
                            unit_given=unit != "s" or time_unit is not None)  # fmt: skip
    rows = table.rows[: data["u"].size]
    status = None if status_col is None else np.array([r[status_col].strip() for r in rows])
    return Recording(
        u=data["u"], y=data["y"], t=t, metadata=table.meta, path=str(table.path), notes=tuple(notes), status=status
    )


def read_column(path: str | os.PathLike[str], column: str = "u") -> tuple[np.ndarray, dict[str, str]]:
    """One column of a CSV file in the recording format (an excitation to replay), and the file's metadata.

    Parameters
    ----------
    path : path-like
        The file: metadata lines, a header row, rows.
    column : str
        The column to read.

    Raises
    ------
    DataError
        As :func:`read_recording`: the column missing or named twice, a value
        not a finite number, no rows.
    """
    table = _read_table(path)
    data, _ = table.numbers(table.locate({"value": column}))
    return data["value"], table.meta


@dataclass(frozen=True)
class _Table:
    """A CSV file split into metadata, header and rows, not yet parsed into numbers."""

    path: Path
    meta: dict[str, str]
    header: list[str]
    rows: list[list[str]]
    first_row: int  # 1-based line number of the header
    complete: bool  # ends with a newline, as the writer leaves every row

    def locate(self, wanted: Mapping[str, str]) -> dict[str, int]:
        """Where each wanted column is; refuses missing columns and names that appear twice."""
        missing = [name for name in wanted.values() if name not in self.header]
        if missing:
            raise DataError(
                f"{self.path}: missing column(s) {', '.join(map(repr, missing))}; "
                f"the header has {', '.join(map(repr, self.header))}"
            )
        for name in wanted.values():
            where = [i + 1 for i, h in enumerate(self.header) if h == name]
            if len(where) > 1:
                raise DataError(
                    f"{self.path}: column {name!r} appears {len(where)} times in the header (columns "
                    f"{', '.join(map(str, where))}); rename all but one"
                )
        return {key: self.header.index(name) for key, name in wanted.items()}

    def numbers(
        self, cols: Mapping[str, int], may_be_nan: set[str] | frozenset[str] = frozenset()
    ) -> tuple[dict[str, np.ndarray], list[str]]:
        """The columns ``cols`` as float arrays, and notes (a truncated last line dropped)."""
        rows = self.rows
        notes: list[str] = []
        if rows and not self.complete:
            # The writer ends every row with a newline: a last line without one was
            # cut off mid-write (crash, kill). Keep it only if it parses whole.
            try:
                _parse_row(rows[-1], self.header, cols, self.path, self.first_row + len(rows), may_be_nan)
            except DataError:
                rows = rows[:-1]
                notes.append("dropped a truncated last line (the recording was cut off while writing)")
        if not rows:
            raise DataError(f"{self.path}: the header is there but no data rows follow")
        data = {key: np.empty(len(rows)) for key in cols}
        for i, row in enumerate(rows):
            for key, value in _parse_row(row, self.header, cols, self.path, self.first_row + 1 + i, may_be_nan).items():
                data[key][i] = value
        return data, notes


def _read_table(path: str | os.PathLike[str]) -> _Table:
    p = Path(path)
    text = read_text(p, what="CSV file")
    lines = text.splitlines()
    meta, body = split_metadata(lines)
    if not body:
        raise DataError(f"{p}: no header row (expected column names such as 't,u,y')")
    first_row = len(lines) - len(body) + 1
    reader = csv.reader(io.StringIO("\n".join(body)))
    try:
        header = [h.strip() for h in next(reader)]
        rows = [r for r in reader if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        # the only failure of a reader over a string: a field over csv.field_size_limit()
        raise DataError(
            f"{p}, line {first_row - 1 + reader.line_num}: {exc} (a field over {csv.field_size_limit()} "
            f"characters: not a recording CSV)"
        ) from None
    return _Table(p, meta, header, rows, first_row, text.endswith("\n"))


def check_magnitudes(arrays: Mapping[str, np.ndarray], *, where: str) -> None:
    """Refuse values beyond :data:`~servoid.limits.MAX_MAGNITUDE`, naming the first (NaN passes: a missed sample).

    A value like ``-1e300`` is finite yet no position a bench measures (a
    wrong unit, a corrupted line), and its square is not finite: refused by
    name before any work, rather than ending in a divergence.

    Parameters
    ----------
    arrays : mapping
        The source's name of each series (a column, a variable) to its values.
    where : str
        The source (a path), for the message.

    Raises
    ------
    DataError
        Naming the series, the index and the value, and how many such values there are.
    """
    for name, values in arrays.items():
        try:
            limits.magnitudes(name, values)
        except ConfigError as exc:
            raise DataError(f"{where}: {exc}") from None


def check_time(
    t: np.ndarray, *, where: str, first_line: int | None = None, column: str = "t", unit_given: bool = True
) -> list[str]:
    """Check that time stamps increase strictly; return notes on gaps and an unlikely unit.

    Parameters
    ----------
    t : ndarray
        Time of each sample, seconds.
    where : str
        The source, for the messages (a path).
    first_line : int, optional
        Line number of ``t[0]`` in a text file; the messages then name lines,
        else sample indices.
    column : str
        Name of the time column or variable, for the messages.
    unit_given : bool
        Whether the unit of ``t`` was stated; if not, a sample period over a
        second is noted as a time column probably in another unit.

    Raises
    ------
    DataError
        At the first stamp that repeats or goes back, naming it.
    """
    notes: list[str] = []
    if t.size < 2:
        return notes
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0.0))
    if bad.size:
        k = int(bad[0]) + 1
        at = f"line {first_line + k}" if first_line is not None else f"sample {k}"
        now, before = float(t[k]), float(t[k - 1])
        what = "repeats the one before" if now == before else f"is earlier than the one before ({before!r} s)"
        raise DataError(
            f"{where}, {at}: {column} (={now!r} s) {what}; time must increase strictly "
            f"({bad.size} of {dt.size} steps do not: reversed, shuffled or constant?). Sort the rows, "
            f"or read them without time as equally spaced samples (--time-column none; time_column=NO_TIME)"
        )
    median = float(np.median(dt))
    if not unit_given and median > _SLOW_PERIOD_S:
        notes.append(
            f"the median sample period is {median:.6g} s: if {column} is not in seconds, give its unit "
            f"({', '.join(u for u in TIME_UNITS if u != 's')})"
        )
    gaps = np.flatnonzero(dt > _GAP_FACTOR * median)
    if gaps.size:
        k = int(gaps[np.argmax(dt[gaps])])
        at = f"line {first_line + k + 1}" if first_line is not None else f"sample {k + 1}"
        notes.append(
            f"{gaps.size} gap(s) in time longer than {_GAP_FACTOR:g} sample periods (median {median:.6g} s), the "
            f"longest {float(dt[k]):.6g} s before {at}; identification takes the samples as equally spaced"
        )
    return notes


def _parse_row(
    row: list[str],
    header: list[str],
    cols: Mapping[str, int],
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
        # an unbuffered descriptor: one os.write per row hands it to the operating system at once (what a
        # flushed text file does, without the text layer's encoding and buffer copies at every sample)
        self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        head = [f"# {key}: {value}\n" for key, value in (metadata or {}).items()]
        self._write("".join(head) + ",".join(self.columns) + "\n")

    def append(self, *values: Any) -> None:
        """Write one row (one value per column, in order) and flush it."""
        if self._fd is None:
            raise DataError(f"{self.path}: the recording is closed")
        if len(values) != len(self.columns):
            raise DataError(f"a row needs {len(self.columns)} values ({', '.join(self.columns)}), got {len(values)}")
        # repr of a float directly: the one per-value cost of a row that the loop pays at every sample
        self._write(",".join([repr(v) if type(v) is float else _format(v) for v in values]) + "\n")
        self.rows += 1
        if self._fsync_every and self.rows % self._fsync_every == 0:
            os.fsync(self._fd)

    def append_line(self, line: str) -> None:
        """Write one row already formatted as a CSV line ending in a newline (:meth:`Sample.line <servoid.session.Sample.line>`) and flush it.

        Parameters
        ----------
        line : str
            The row's text, as :meth:`append` would write it.
        """
        if self._fd is None:
            raise DataError(f"{self.path}: the recording is closed")
        self._write(line)
        self.rows += 1
        if self._fsync_every and self.rows % self._fsync_every == 0:
            os.fsync(self._fd)

    def _write(self, text: str) -> None:
        assert self._fd is not None
        data = text.encode()
        written = os.write(self._fd, data)
        while written < len(data):  # a short write (a signal, a nearly full disk): the rest, in order
            data = data[written:]
            written = os.write(self._fd, data)

    def close(self) -> None:
        """Flush, sync and close; safe to call more than once."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                os.fsync(fd)
            finally:
                os.close(fd)

    def __del__(self) -> None:  # a writer dropped unclosed: its descriptor goes back (the rows are written already)
        fd = getattr(self, "_fd", None)
        if fd is not None:
            os.close(fd)

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
