"""Values ready for strict JSON, and the one ``dumps`` servoid writes JSON with.

Every result type has a ``to_dict()`` built from plain values; this module
turns what JSON cannot hold into what it can: NaN and infinities become
``null`` (a result that can be undetermined says why next to it, e.g.
``fit_reason``), NumPy numbers and arrays plain numbers and lists, tuples
lists, paths strings. :func:`dumps` applies it and refuses anything left
over (``allow_nan=False``), so no NaN ever reaches a file or ``--json``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["json_ready", "number", "dumps"]


def number(value: float | None) -> float | None:
    """``value`` as a float, or None when it is None, NaN or infinite.

    Parameters
    ----------
    value : float or None
        A number that may be undetermined.
    """
    if value is None:
        return None
    v = float(value)
    return v if math.isfinite(v) else None


def json_ready(obj: Any) -> Any:
    """``obj`` with every value JSON can hold (see the module docstring), recursively.

    Parameters
    ----------
    obj : any
        Mappings, sequences, numbers, strings, NumPy values, paths.
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)) and not isinstance(obj, np.bool_):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return number(float(obj))
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, Mapping):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        return [json_ready(v) for v in obj.tolist()]
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON: give the result's to_dict()")


def dumps(obj: Any, *, indent: int | None = None) -> str:
    """Strict JSON text of ``obj`` (after :func:`json_ready`; never NaN or Infinity).

    Parameters
    ----------
    obj : any
        What :func:`json_ready` accepts.
    indent : int, optional
        Pretty-print with this indent (None: one line, as a JSON Lines record).
    """
    return json.dumps(json_ready(obj), indent=indent, allow_nan=False)
