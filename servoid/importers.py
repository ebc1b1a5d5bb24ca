"""Read bench logs made by others into servoid recordings.

Two public formats that hold real servo data:

EMPS (``DATA_EMPS.mat``, ``DATA_EMPS_PULSES.mat``)
    The Electro-Mechanical Positioning System benchmark (Janot, Gautier,
    Brunot): MATLAB v5 files with ``t`` [s], ``qg`` reference position [m],
    ``qm`` motor position [m], sampled at 1 kHz. servoid takes ``u = qg`` and
    ``y = qm``.
BAM (``bam_*.json``)
    Servo-pendulum logs of Rhoban's "Better Actuator Models": a JSON object
    whose ``entries`` hold ``timestamp`` [s], ``goal_position`` [rad] and
    ``position`` [rad]. servoid takes ``u = goal_position`` and ``y = position``.

Each reader returns a :class:`~servoid.recording.Recording`; write it with
:func:`to_csv` to get a file ``servoid diagnose`` and ``servoid identify`` read.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, DataError
from servoid.files import existing_file, read_json
from servoid.recording import Recording, write_recording

__all__ = ["read_emps", "read_bam", "to_csv", "split"]


def _decimate(rec: Recording, factor: int) -> Recording:
    """Keep every ``factor``-th sample.

    No anti-alias filter: the EMPS and BAM positions are smooth at their
    sampling rates, and a filter would add a phase lag to ``y`` that the
    model would then have to explain.
    """
    if factor == 1:
        return rec
    t = None if rec.t is None else rec.t[::factor]
    meta = dict(rec.metadata, decimated_by=str(factor))
    return Recording(u=rec.u[::factor], y=rec.y[::factor], t=t, metadata=meta, path=rec.path, notes=rec.notes)


def read_emps(path: str | os.PathLike[str], *, decimate: int = 1) -> Recording:
    """Read an EMPS ``.mat`` file: ``u = qg`` (reference), ``y = qm`` (motor position), in metres.

    Parameters
    ----------
    path : path-like
        ``DATA_EMPS.mat`` or ``DATA_EMPS_PULSES.mat``.
    decimate : int
        Keep every ``decimate``-th sample (the files are at 1 kHz).

    Raises
    ------
    DataError
        Missing file, not a MATLAB file, or missing ``qg``/``qm``/``t``.
    """
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    factor = _factor(decimate)
    p = existing_file(path)
    try:
        data = loadmat(p)
    except (MatReadError, ValueError, OSError, IndexError, TypeError) as exc:  # scipy's reader fails in many ways
        raise DataError(f"{p}: not a MATLAB .mat file ({exc})") from exc
    missing = [k for k in ("t", "qg", "qm") if k not in data]
    if missing:
        raise DataError(f"{p}: missing variable(s) {', '.join(missing)}; an EMPS file has t, qg, qm")
    t, u, y = (np.asarray(data[k], dtype=np.float64).ravel() for k in ("t", "qg", "qm"))
    if not (t.size == u.size == y.size):
        raise DataError(f"{p}: t, qg and qm differ in length ({t.size}, {u.size}, {y.size})")
    meta = {"source": f"EMPS {p.name}", "unit": "m", "input_unit": "m", "u": "qg (reference position)",
            "y": "qm (motor position)"}  # fmt: skip
    return _decimate(Recording(u=u, y=y, t=t, metadata=meta, path=str(p)), factor)


def read_bam(path: str | os.PathLike[str], *, decimate: int = 1) -> Recording:
    """Read a BAM servo-pendulum JSON log: ``u = goal_position``, ``y = position``, in rad.

    Raises
    ------
    DataError
        Missing file, not JSON, or entries without ``timestamp``, ``goal_position`` or ``position``.
    """
    factor = _factor(decimate)
    p = Path(path)
    data = read_json(p)
    entries = data.get("entries") if isinstance(data, dict) else None
    if not isinstance(entries, list) or not entries:
        raise DataError(
            f"{p}: no 'entries' list; a BAM log is {{..., 'entries': [{{timestamp, goal_position, position}}]}}"
        )
    try:
        t = np.array([float(e["timestamp"]) for e in entries])
        u = np.array([float(e["goal_position"]) for e in entries])
        y = np.array([float(e["position"]) for e in entries])
    except (KeyError, TypeError, ValueError) as exc:
        raise DataError(f"{p}: an entry lacks timestamp, goal_position or position ({exc!r})") from None
    meta = {"source": f"BAM {p.name} ({data.get('motor', 'servo')})", "unit": "rad", "input_unit": "rad",
            "u": "goal_position", "y": "position"}  # fmt: skip
    return _decimate(Recording(u=u, y=y, t=t - t[0], metadata=meta, path=str(p)), factor)


def split(rec: Recording, fraction: float = 0.5) -> tuple[Recording, Recording]:
    """Cut a recording in two at ``fraction`` of its length (training first, validation second)."""
    frac = validation.in_unit_interval("fraction", fraction)
    k = int(round(frac * len(rec)))
    if k < 1 or k >= len(rec):
        raise ConfigError(f"fraction (={fraction}) leaves one part of {len(rec)} samples empty")
    parts = []
    for sl, name in ((slice(0, k), "first"), (slice(k, None), "second")):
        t = None if rec.t is None else rec.t[sl]
        meta = dict(rec.metadata, part=f"{name} {frac if name == 'first' else 1 - frac:.0%}")
        parts.append(Recording(u=rec.u[sl], y=rec.y[sl], t=t, metadata=meta, path=rec.path))
    return parts[0], parts[1]


def to_csv(rec: Recording, path: str | os.PathLike[str]) -> Path:
    """Write ``rec`` as a servoid recording CSV (``t`` when known, ``u``, ``y``; metadata as ``#`` lines)."""
    cols: dict[str, np.ndarray] = {}
    if rec.t is not None:
        cols["t"] = rec.t
    cols["u"] = rec.u
    cols["y"] = rec.y
    return write_recording(path, cols, metadata=rec.metadata)


def _factor(decimate: int) -> int:
    return validation.integer("decimate", decimate, minimum=1)
