"""Reading the files servoid is given: one place for the checks and their messages.

Every failure is a :class:`~servoid.errors.DataError` whose one line names the
file and what is wrong with it (missing, a folder, not UTF-8 text, not JSON,
too large, nested too deep, a number JSON has no room for), never a
traceback from ``open`` or ``json``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from servoid.errors import DataError
from servoid.limits import MAX_JSON_DEPTH

__all__ = ["existing_file", "read_text", "read_json", "json_depth"]


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


def read_json(
    path: str | os.PathLike[str], *, what: str = "file", max_bytes: int | None = None, non_finite: bool = False
) -> Any:
    """The file parsed as JSON (see :func:`existing_file` for ``what``), nested at most ``MAX_JSON_DEPTH`` deep.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file should be, for the message.
    max_bytes : int, optional
        Refuse a larger file before reading it.
    non_finite : bool
        Accept ``NaN``, ``Infinity`` and ``-Infinity`` (not JSON, but what
        Python's ``json`` writes by default); refused by default.
    """
    p = existing_file(path, what=what)
    if max_bytes is not None:
        size = p.stat().st_size
        if size > max_bytes:
            raise DataError(f"{p}: {size} bytes is too large for a {what} (at most {max_bytes})")
    text = read_text(p, what=what)

    def constant(name: str) -> float:
        if not non_finite:
            raise DataError(f"{p}: {name} is not a JSON number (a {what} holds finite numbers, or null)")
        return float(name.replace("Infinity", "inf"))

    try:
        data = json.loads(text, parse_constant=constant)
    except RecursionError:
        raise DataError(f"{p}: nested deeper than a {what} can be (at most {MAX_JSON_DEPTH} levels)") from None
    except json.JSONDecodeError as exc:
        raise DataError(f"{p}: not a JSON file ({exc})") from exc
    except DataError:
        raise
    except ValueError as exc:  # an integer beyond Python's 4300-digit limit for str -> int
        raise DataError(f"{p}: a number has more digits than a {what} can hold ({str(exc).split(';')[0]})") from None
    depth = json_depth(data)
    if depth > MAX_JSON_DEPTH:
        raise DataError(f"{p}: nested {depth} levels deep; a {what} has at most {MAX_JSON_DEPTH}")
    return data


def json_depth(data: Any) -> int:
    """How deep ``data`` (parsed JSON) nests: 0 for a number or a string, 1 for ``[]`` or ``{}``, ...

    Walks without recursion, so that any depth Python's parser could build is measured.
    """
    deepest = 0
    stack: list[tuple[Any, int]] = [(data, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict):
            children: Any = node.values()
        elif isinstance(node, list):
            children = node
        else:
            continue
        depth += 1
        deepest = max(deepest, depth)
        stack.extend((child, depth) for child in children)
    return deepest
