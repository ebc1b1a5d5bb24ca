"""A recording read for a command: the reader's notes shown as warnings, every value within servoid's limits."""

from __future__ import annotations

import os

from servoid import limits
from servoid.cli import _term
from servoid.errors import ConfigError, DataError
from servoid.recording import Recording, read_recording

__all__ = ["read_checked"]


def read_checked(path: str | os.PathLike[str]) -> Recording:
    """Read the recording at ``path``; warn its notes; refuse values beyond :data:`~servoid.limits.MAX_MAGNITUDE`.

    A value like ``-1e300`` is finite yet no position a bench measures (a
    wrong unit, a corrupted line), and its square is not finite: refused by
    name before any work, rather than ending in a divergence.

    Parameters
    ----------
    path : path-like
        The recording (CSV).

    Raises
    ------
    DataError
        What the reader refuses, or a value beyond the limit (named by column and index).
    """
    rec = read_recording(path)
    for note in rec.notes:
        _term.warn(f"{path}: {note}")
    try:
        limits.magnitudes("u", rec.u)
        limits.magnitudes("y", rec.y)
    except ConfigError as exc:
        raise DataError(f"{path}: {exc}") from None
    return rec
