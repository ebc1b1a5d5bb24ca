"""BAM servo-pendulum logs (Rhoban's "Better Actuator Models"): a JSON object whose ``entries`` are the samples.

Each entry holds ``timestamp`` [s], ``goal_position`` [rad] and ``position``
[rad] (and speed, load, voltage, temperature); servoid takes
``u = goal_position``, ``y = position`` and ``t = timestamp``, or other fields
of the entries when named.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal

from servoid import validation
from servoid.errors import DataError
from servoid.files import read_json
from servoid.readers._series import assemble, listing, series
from servoid.recording import NO_TIME, Recording

__all__ = ["read_bam"]


def read_bam(
    path: str | os.PathLike[str],
    *,
    decimate: int = 1,
    u: str = "goal_position",
    y: str = "position",
    t: str | Literal[False] = "timestamp",
) -> Recording:
    """Read a BAM servo-pendulum JSON log; time starts at 0.

    Parameters
    ----------
    path : path-like
        The ``.json`` log.
    decimate : int
        Keep every ``decimate``-th sample.
    u, y : str
        The fields of each entry that hold the input and the output.
    t : str or False
        The field that holds the time (seconds); False reads none.

    Raises
    ------
    DataError
        Missing file, not JSON, no ``entries`` list, an entry without a field
        asked for (the message names it and lists the entry's fields), a
        value that is not a finite number, or time not increasing.
    """
    factor = validation.integer("decimate", decimate, minimum=1)
    p = Path(path)
    data = read_json(p, what="BAM log")
    entries = data.get("entries") if isinstance(data, dict) else None
    if not isinstance(entries, list) or not entries:
        raise DataError(f"{p}: no 'entries' list; a BAM log is {{..., 'entries': [{{{t}, {u}, {y}}}]}}")
    names = {"u": u, "y": y} if t is NO_TIME else {"u": u, "y": y, "t": str(t)}
    arrays = {role: series(_field(entries, name, p), what=f"field {name!r} of {p}") for role, name in names.items()}
    if "t" in arrays:
        arrays["t"] = arrays["t"] - arrays["t"][0]
    motor = data.get("motor", "servo") if isinstance(data, dict) else "servo"
    meta = {"source": f"BAM {p.name} ({motor})", "unit": "rad", "input_unit": "rad", "u": u, "y": y}
    rec = assemble(arrays, names=names, where=str(p), time_unit="s", metadata=meta, path=str(p))
    return rec.decimated(factor)


def _field(entries: list[Any], name: str, p: Path) -> list[Any]:
    out = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise DataError(f"{p}: entry {i} is a {type(entry).__name__}, not an object of fields (such as {name!r})")
        if name not in entry:
            raise DataError(f"{p}: entry {i} has no field {name!r}; it has {listing({k: '' for k in entry})}")
        out.append(entry[name])
    return out
