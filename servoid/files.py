"""Reading the files servoid is given: one place for the checks and their messages.

Every failure is a :class:`~servoid.errors.DataError` whose one line names the
file and what is wrong with it (missing, a folder, not UTF-8 text, not JSON),
never a traceback from ``open`` or ``json``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from servoid.errors import DataError

__all__ = ["existing_file", "read_text", "read_json"]


def existing_file(path: str | os.PathLike[str], *, what: str = "file") -> Path:
    """``path`` as a :class:`~pathlib.Path`, checked to be a file.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file should be, for the message (``"model file"``, ``"CSV file"``).
    """
    p = Path(path)
    if p.is_dir():
        raise DataError(f"{p} is a directory, expected a {what}")
    if not p.is_file():
        raise DataError(f"{p}: no such {what}")
    return p


def read_text(path: str | os.PathLike[str], *, what: str = "file") -> str:
    """The whole file as UTF-8 text (see :func:`existing_file` for ``what``)."""
    p = existing_file(path, what=what)
    try:
        return p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{p}: cannot read as UTF-8 text ({exc})") from exc


def read_json(path: str | os.PathLike[str], *, what: str = "file") -> Any:
    """The file parsed as JSON (see :func:`existing_file` for ``what``)."""
    text = read_text(path, what=what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise DataError(f"{Path(path)}: not a JSON file ({exc})") from exc
