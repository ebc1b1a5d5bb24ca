"""Identifying a fleet: one job per recording (run on a Dask worker) and the table of every joint's play and its trend.

:func:`identify_file` is the job: it reads one recording with
:func:`servoid.readers.read`, identifies it (:func:`servoid.ident.identify.identify`)
and returns a :class:`Done` -- the table's row and the model file's text --
or the row with the error when the recording cannot be read or identified,
so that one bad file never stops the others; it runs its fit on the calling
thread only (:func:`servoid.ident.offline._threads.one_thread`), since the
workers already use one core each. The caller (the ``servoid
batch`` command, which distributes the jobs with Dask) writes what comes
back: each row as ``rows/<key>.json`` the moment it arrives, which is what
makes a run resumable (:func:`done_keys`), and each model as
``models/<key>.json``. :func:`fleet_table` adds the trend of the play per
servo across recordings; :func:`write_table` writes the table as CSV and
Parquet.

Fields that issue 12's pipeline adds to the identification (``structure``,
``identifiable``, a ``play_interval``) are read from the result when it has
them; until then the structure is the pseudo-Wiener model's, the interval is
``play +- 1.96`` standard errors of ``c1 + c2`` from the refinement's
covariance, and ``identifiable`` is left empty (unknown), never guessed.
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import json
import math
import os
import re
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid import readings_side

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.identify import Identification
    from servoid.ident.online.mrgia import MRGIAConfig
    from servoid.readers import ReadOptions
    from servoid.recording import Recording

__all__ = [
    "COLUMNS",
    "Done",
    "identify_file",
    "recording_key",
    "done_keys",
    "save_done",
    "load_rows",
    "fleet_table",
    "write_table",
    "servo_id_of",
    "time_of",
]

#: Columns of the fleet table, in order.
COLUMNS = (
    "servo_id", "time", "play", "play_low", "play_high", "unit", "structure", "fit_nrmse", "identifiable",
    "play_trend_per_day", "trend_recordings", "samples", "method", "recording", "model", "warnings", "error",
)  # fmt: skip

#: Two-sided 95 % normal quantile, for the play's interval from its standard error.
Z95 = 1.959963984540054

#: A date and time in a file name: 2024-10-26_12h23m27, 20240115T102810, 2026-01-15 10:28:10, ...
_STAMP = re.compile(
    r"(?P<y>\d{4})-?(?P<mo>\d{2})-?(?P<d>\d{2})(?:[_T \-]?(?P<h>\d{2})[h:\-]?(?P<mi>\d{2})[m:\-]?(?P<s>\d{2})s?)?"
)


@dataclass(frozen=True)
class Done:
    """What one job returns: the table's row and, when it succeeded, the model file's text.

    Attributes
    ----------
    key : str
        The recording's key (:func:`recording_key`).
    row : dict
        One value per name in :data:`COLUMNS` but the trend's (``error`` set when it failed).
    model_json : str or None
        The ``model.json`` text; None when the recording failed.
    """

    key: str
    row: dict[str, Any]
    model_json: str | None


def recording_key(path: str | os.PathLike[str]) -> str:
    """A file name for a recording's outputs: its name and a hash of its absolute path, size and modification time.

    A recording that changed on disk gets a new key, so a resumed run
    identifies it again.

    Parameters
    ----------
    path : path-like
        The recording (a file or a ROS 2 bag folder).
    """
    p = Path(path).resolve()
    try:
        st = p.stat()
        stamp = f"{st.st_size}:{st.st_mtime_ns}"
    except OSError:
        stamp = "missing"
    digest = hashlib.sha256(f"{p}\0{stamp}".encode("utf-8", "surrogateescape")).hexdigest()[:12]
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", p.name)[:80]
    return f"{name}-{digest}"


def servo_id_of(path: str | os.PathLike[str], metadata: Mapping[str, str]) -> str:
    """Which servo a recording is of: its ``servo_id`` (or ``servo``) metadata, else its name without a date and time.

    Parameters
    ----------
    path : path-like
        The recording.
    metadata : mapping
        Its ``# key: value`` lines (or a reader's metadata).
    """
    for key in ("servo_id", "servo"):
        value = metadata.get(key)
        if value:
            return str(value).strip()
    stem = Path(path).stem if Path(path).suffix else Path(path).name
    stripped = _STAMP.sub("", stem).strip("_- .")
    return stripped or stem


def time_of(path: str | os.PathLike[str], metadata: Mapping[str, str]) -> str:
    """When a recording was made (ISO 8601): its ``started`` metadata, a date in its name, else its file's time.

    Parameters
    ----------
    path : path-like
        The recording.
    metadata : mapping
        Its metadata.
    """
    started = metadata.get("started")
    if started:
        try:
            return _iso(_dt.datetime.strptime(started.strip(), "%Y-%m-%dT%H:%M:%S%z"))
        except ValueError:
            pass
    m = _STAMP.search(Path(path).name)
    if m:
        try:
            y, mo, d, h, mi, sec = (int(m.group(g) or 0) for g in ("y", "mo", "d", "h", "mi", "s"))
            return _iso(_dt.datetime(y, mo, d, h, mi, sec, tzinfo=_dt.timezone.utc))
        except ValueError:
            pass
    return _iso(_dt.datetime.fromtimestamp(Path(path).stat().st_mtime, tz=_dt.timezone.utc))


def _iso(t: _dt.datetime) -> str:
    return t.astimezone(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def identify_file(path: str, options: ReadOptions, config: MRGIAConfig) -> Done:
    """Read and identify one recording; never raises for a bad recording (the row carries the error).

    Parameters
    ----------
    path : str
        The recording, as the worker sees it (a shared file system on a cluster).
    options : ReadOptions
        How to read it (columns, time unit, topics).
    config : MRGIAConfig
        Orders and estimator settings.
    """
    from servoid.errors import ServoidError
    from servoid.ident.offline._threads import one_thread

    key = recording_key(path)
    row: dict[str, Any] = dict.fromkeys(COLUMNS)
    row.update(recording=str(path), warnings="", error=None)
    try:
        from servoid.readers import read

        rec = read(path, options)
        row["servo_id"] = servo_id_of(path, rec.metadata)
        row["time"] = time_of(path, rec.metadata)
        # the fleet already runs one record per core: a fit's own threads would only oversubscribe it
        with one_thread():
            result = _identify(rec, config)
        row.update(_result_columns(rec, result))
        row["warnings"] = "; ".join([*rec.notes, *result.warnings])
        model_json = _model_json(path, rec, result)
    except (ServoidError, OSError, ValueError, MemoryError) as exc:
        row["error"] = " ".join(f"{type(exc).__name__}: {exc}".split())
        if row["servo_id"] is None:
            row["servo_id"] = servo_id_of(path, {})
        return Done(key, row, None)
    return Done(key, row, model_json)


def _identify(rec: Recording, config: MRGIAConfig) -> Identification:
    from servoid.ident.identify import identify
    from servoid.session.samples import recording_usable

    return identify(rec.u, rec.y, config, valid=recording_usable(rec), record_every=max(1, rec.u.size // 2000),
                    readings=readings_side.of(rec.metadata))  # fmt: skip


def _result_columns(rec: Recording, result: Identification) -> dict[str, Any]:
    """The row's values from an identification, reading issue 12's fields where the result has them."""
    model = result.model
    play = float(model.dead_zone)
    interval = getattr(result, "play_interval", None)
    if interval is None:
        se = _play_stderr(result)
        interval = (play - Z95 * se, play + Z95 * se) if se is not None else (None, None)
    identifiable = getattr(result, "identifiable", None)
    return {
        "play": play,
        "play_low": None if interval[0] is None else float(interval[0]),
        "play_high": None if interval[1] is None else float(interval[1]),
        "unit": rec.metadata.get("unit", "unit"),
        "structure": str(getattr(result, "structure", None) or "pseudo-wiener"),
        "fit_nrmse": _number(result.fit_nrmse),
        "identifiable": None if identifiable is None else bool(identifiable),
        "samples": int(result.samples),
        "method": result.method,
    }


def _play_stderr(result: Identification) -> float | None:
    """Standard error of ``c1 + c2`` from the refinement's covariance (None without one, or undetermined)."""
    ref = result.refinement
    if ref is None:
        return None
    names = list(ref.model.names)  # the covariance's order
    cov = getattr(ref, "covariance", None)
    if cov is None or "c1" not in names or "c2" not in names:
        return None
    i, j = names.index("c1"), names.index("c2")
    var = float(cov[i, i] + cov[j, j] + 2.0 * cov[i, j])
    return math.sqrt(var) if math.isfinite(var) and var >= 0.0 else None


def _number(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def _model_json(path: str, rec: Recording, result: Identification) -> str:
    from servoid.identify_outputs import Record, model_content

    record = Record(u=rec.u, y=rec.y, t=rec.t, source=str(path), output_unit=rec.metadata.get("unit", "unit"),
                    input_unit=rec.metadata.get("input_unit", "unit"), readings=readings_side.of(rec.metadata))  # fmt: skip
    return model_content(record, result).to_json()


# ---- the run's folder: resumable ------------------------------------------------------------------
def done_keys(out_dir: Path) -> set[str]:
    """Keys of the recordings already identified in ``out_dir`` (failed ones are tried again).

    Parameters
    ----------
    out_dir : Path
        The run's folder.
    """
    keys = set()
    for p in (out_dir / "rows").glob("*.json"):
        try:
            row = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue  # a row cut short by a crash: identify that recording again
        if isinstance(row, dict) and row.get("error") is None:
            keys.add(p.stem)
    return keys


def save_done(out_dir: Path, done: Done) -> None:
    """Write a job's model and row into ``out_dir`` (the row last, by rename: a row on disk means done).

    Parameters
    ----------
    out_dir : Path
        The run's folder.
    done : Done
        What the job returned.
    """
    from servoid.ident.serialise import dumps

    rows, models = out_dir / "rows", out_dir / "models"
    rows.mkdir(parents=True, exist_ok=True)
    models.mkdir(parents=True, exist_ok=True)
    row = dict(done.row)
    if done.model_json is not None:
        model_path = models / f"{done.key}.json"
        model_path.write_text(done.model_json, encoding="utf-8")
        row["model"] = str(model_path)
    tmp = rows / f".{done.key}.tmp"
    tmp.write_text(dumps(row), encoding="utf-8")
    os.replace(tmp, rows / f"{done.key}.json")


def load_rows(out_dir: Path, keys: Iterable[str]) -> list[dict[str, Any]]:
    """The saved rows of these recordings (those with no row yet are left out).

    Parameters
    ----------
    out_dir : Path
        The run's folder.
    keys : iterable of str
        Recording keys.
    """
    out = []
    for key in keys:
        p = out_dir / "rows" / f"{key}.json"
        try:
            out.append(json.loads(p.read_text(encoding="utf-8")))
        except (OSError, ValueError):
            continue
    return out


# ---- the table ------------------------------------------------------------------------------------
def fleet_table(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The rows sorted by servo and time, with the trend of the play per servo across its recordings.

    The trend is the least-squares slope of the play against time, in the
    play's unit per day, over the servo's recordings that were identified
    (empty with fewer than two, or all at one time).

    Parameters
    ----------
    rows : sequence of mapping
        One row per recording (:data:`COLUMNS`).
    """
    by_servo: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for r in rows:
        if r.get("error") is None and r.get("play") is not None and r.get("time"):
            by_servo[str(r["servo_id"])].append((_days(str(r["time"])), float(r["play"])))
    trend: dict[str, float | None] = {}
    for servo, points in by_servo.items():
        trend[servo] = _slope(points)
    out = []
    for r in sorted(rows, key=lambda r: (str(r.get("servo_id")), str(r.get("time") or ""), str(r["recording"]))):
        row = {c: r.get(c) for c in COLUMNS}
        row["play_trend_per_day"] = trend.get(str(r.get("servo_id")))
        row["trend_recordings"] = len(by_servo.get(str(r.get("servo_id")), ()))
        out.append(row)
    return out


def _days(iso: str) -> float:
    t = _dt.datetime.fromisoformat(iso.replace("Z", "+00:00"))
    return t.timestamp() / 86400.0


def _slope(points: Sequence[tuple[float, float]]) -> float | None:
    if len(points) < 2:
        return None
    t0 = min(p[0] for p in points)
    ts = [p[0] - t0 for p in points]
    ys = [p[1] for p in points]
    mt, my = sum(ts) / len(ts), sum(ys) / len(ys)
    stt = sum((t - mt) ** 2 for t in ts)
    if stt == 0.0:
        return None
    return sum((t - mt) * (y - my) for t, y in zip(ts, ys)) / stt


def write_table(out_dir: Path, table: Sequence[Mapping[str, Any]]) -> dict[str, Path]:
    """Write the table as ``fleet.csv`` and ``fleet.parquet`` in ``out_dir``; return both paths.

    Parameters
    ----------
    out_dir : Path
        The run's folder.
    table : sequence of mapping
        Rows of :data:`COLUMNS` (:func:`fleet_table`).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    csv_path, parquet_path = out_dir / "fleet.csv", out_dir / "fleet.parquet"
    with open(csv_path, "w", encoding="utf-8", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        for row in table:
            writer.writerow(["" if row.get(c) is None else _cell(row.get(c)) for c in COLUMNS])
    schema = pa.schema([
        ("servo_id", pa.string()), ("time", pa.timestamp("s", tz="UTC")), ("play", pa.float64()),
        ("play_low", pa.float64()), ("play_high", pa.float64()), ("unit", pa.string()), ("structure", pa.string()),
        ("fit_nrmse", pa.float64()), ("identifiable", pa.bool_()), ("play_trend_per_day", pa.float64()),
        ("trend_recordings", pa.int64()), ("samples", pa.int64()), ("method", pa.string()),
        ("recording", pa.string()), ("model", pa.string()), ("warnings", pa.string()), ("error", pa.string()),
    ])  # fmt: skip
    columns = {c: [row.get(c) for row in table] for c in COLUMNS}
    columns["time"] = [None if t is None else _dt.datetime.fromisoformat(str(t).replace("Z", "+00:00"))
                       for t in columns["time"]]  # fmt: skip
    pq.write_table(pa.table(columns, schema=schema), parquet_path)
    return {"csv": csv_path, "parquet": parquet_path}


def _cell(value: Any) -> str:
    return repr(value) if isinstance(value, float) else str(value)
