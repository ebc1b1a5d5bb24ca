"""MATLAB ``.mat`` files: named variables as input, output and time (v4 to v7 with SciPy, v7.3 with h5py).

A variable is named as MATLAB names it: ``qm``, a field of a struct
``log.position``, or one column (or row) of a matrix ``data(:,2)``
(1-based, as in MATLAB). v7.3 files are HDF5 files; they need ``h5py``
(``pip install 'servoid[mat]'``).

The EMPS benchmark (``DATA_EMPS.mat``, ``DATA_EMPS_PULSES.mat``) is
:func:`read_emps`: ``u = qg`` (reference position), ``y = qm`` (motor
position), ``t`` in seconds, all in metres.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Literal

import numpy as np

from servoid import validation
from servoid.errors import DataError, MissingDependency
from servoid.files import existing_file
from servoid.readers._series import assemble, listing, series
from servoid.recording import NO_TIME, Recording

__all__ = ["read_mat", "read_emps", "read_mat_variable", "mat_variables"]

#: ``name(:,j)`` or ``name(i,:)``: one column or row of a matrix, 1-based.
_SLICE = re.compile(r"^\s*([A-Za-z_][\w.]*)\s*\(\s*(?::\s*,\s*(\d+)|(\d+)\s*,\s*:)\s*\)\s*$")


def read_mat(
    path: str | os.PathLike[str],
    *,
    u: str = "u",
    y: str = "y",
    t: str | None | Literal[False] = None,
    time_unit: str | None = None,
) -> Recording:
    """Read the input, output and time of a MATLAB file from named variables.

    Parameters
    ----------
    path : path-like
        The ``.mat`` file.
    u, y : str
        The variables holding the input and the measured output: ``name``,
        ``struct.field`` or ``matrix(:,j)`` (1-based).
    t : str, None or False
        The time variable; None reads ``t`` when the file has it, False none.
    time_unit : str, optional
        Unit of the time variable (``s``, ``ms``, ``us``, ``ns``; default seconds).

    Raises
    ------
    DataError
        Not a MATLAB file, a variable missing (the message lists the file's
        variables with their sizes), not numeric, a matrix where a vector is
        needed, non-finite values, lengths that differ, time not increasing.
    MissingDependency
        A v7.3 file without h5py installed.
    """
    p = existing_file(path, what="MATLAB file")
    variables = _load(p)
    wanted = {"u": u, "y": y}
    if t is None:
        if "t" in variables.names:
            wanted["t"] = "t"
    elif t is not NO_TIME:
        wanted["t"] = str(t)
    arrays = {role: series(variables.get(name), what=f"variable {name!r} of {p}") for role, name in wanted.items()}
    meta = {"source": f"MATLAB {p.name}", "u": wanted["u"], "y": wanted["y"]}
    return assemble(arrays, names=wanted, where=str(p), time_unit=time_unit, metadata=meta, path=str(p))


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
    factor = validation.integer("decimate", decimate, minimum=1)
    rec = read_mat(path, u="qg", y="qm", t="t")
    meta = {"source": f"EMPS {Path(path).name}", "unit": "m", "input_unit": "m", "u": "qg (reference position)",
            "y": "qm (motor position)"}  # fmt: skip
    return rec.with_metadata(meta).decimated(factor)


def read_mat_variable(path: str | os.PathLike[str], name: str) -> np.ndarray:
    """One variable of a MATLAB file as a vector (``name``, ``struct.field`` or ``matrix(:,j)``).

    Parameters
    ----------
    path : path-like
        The ``.mat`` file.
    name : str
        The variable.
    """
    p = existing_file(path, what="MATLAB file")
    return series(_load(p).get(name), what=f"variable {name!r} of {p}")


def mat_variables(path: str | os.PathLike[str]) -> dict[str, str]:
    """The variables of a MATLAB file and their sizes (``{"qm": "24841x1", ...}``), as a reader would see them."""
    return dict(_load(existing_file(path, what="MATLAB file")).shapes)


class _Variables:
    """Named arrays of one file, looked up by MATLAB's names; lists them when one is missing."""

    def __init__(self, path: Path, top: dict[str, Any], shapes: dict[str, str]) -> None:
        self.path = path
        self.top = top
        self.shapes = shapes
        self.names = set(top)

    def get(self, name: str) -> Any:
        match = _SLICE.match(name)
        base = match.group(1) if match else name.strip()
        parts = base.split(".")
        value: Any = self.top.get(parts[0])
        for part in parts[1:]:
            value = _field(value, part)
        if value is None:
            raise DataError(f"{self.path}: no variable {base!r}; the file has {listing(self.shapes)}")
        if match is None:
            return value
        arr = np.asarray(value)
        if arr.ndim != 2:
            raise DataError(f"{self.path}: {base!r} is not a matrix, {name!r} cannot take one of its columns")
        col, row = match.group(2), match.group(3)
        index, axis = (int(col), 1) if col is not None else (int(row), 0)
        if not 1 <= index <= arr.shape[axis]:
            size = "x".join(map(str, arr.shape))
            raise DataError(f"{self.path}: {name!r} is outside {base!r}, a {size} matrix (indices start at 1)")
        return arr[:, index - 1] if axis == 1 else arr[index - 1, :]


def _field(value: Any, name: str) -> Any:
    """A struct's field, from SciPy's record arrays or h5py's groups (None when absent)."""
    if value is None:
        return None
    if hasattr(value, "keys"):  # an h5py group
        return value[name] if name in value else None
    arr = np.asarray(value)
    if arr.dtype.names is None or name not in arr.dtype.names:
        return None
    return arr.reshape(-1)[0][name]


def _load(path: Path) -> _Variables:
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    try:
        data = loadmat(path)
    except NotImplementedError:  # SciPy's answer to a v7.3 (HDF5) file
        return _load_hdf5(path)
    except (MatReadError, ValueError, OSError, IndexError, TypeError, EOFError) as exc:  # SciPy fails in many ways
        raise DataError(f"{path}: not a MATLAB .mat file ({exc})") from None
    top = {k: v for k, v in data.items() if not k.startswith("__")}
    shapes = {k: _shape(v) for k, v in top.items()}
    return _Variables(path, top, shapes)


def _shape(value: Any) -> str:
    arr = np.asarray(value)
    if arr.dtype.names:
        return "struct: " + " ".join(arr.dtype.names)
    kind = "" if arr.dtype.kind in "biuf" else " " + _KINDS.get(arr.dtype.kind, "other")
    return "x".join(map(str, arr.shape)) + kind


_KINDS = {"U": "text", "S": "text", "O": "cell", "c": "complex"}


def _load_hdf5(path: Path) -> _Variables:
    try:
        import h5py
    except ImportError:
        raise MissingDependency(
            f"{path} is a MATLAB v7.3 (HDF5) file, which needs h5py: pip install 'servoid[mat]' "
            f"(or save it from MATLAB with save(..., '-v7'))"
        ) from None
    try:
        handle = h5py.File(path, "r")
    except OSError as exc:
        raise DataError(f"{path}: not a readable MATLAB v7.3 (HDF5) file ({exc})") from None
    with handle:
        top: dict[str, Any] = {}
        shapes: dict[str, str] = {}
        for name, item in handle.items():
            if name.startswith("#"):  # MATLAB's references and subsystem, not variables
                continue
            top[name], shapes[name] = _hdf5_value(item)
    return _Variables(path, top, shapes)


def _hdf5_value(item: Any) -> tuple[Any, str]:
    """A dataset as MATLAB shapes it (HDF5 stores MATLAB's arrays transposed), a group as a dict."""
    if hasattr(item, "keys"):
        fields = {k: _hdf5_value(v)[0] for k, v in item.items()}
        return fields, "struct: " + " ".join(fields)
    matlab_class = item.attrs.get("MATLAB_class", b"double")
    matlab_class = matlab_class.decode() if isinstance(matlab_class, bytes) else str(matlab_class)
    arr = np.asarray(item[()]).T
    shape = "x".join(map(str, arr.shape))
    if matlab_class not in ("double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
                            "uint64", "logical"):  # fmt: skip
        return matlab_class, f"{shape} {matlab_class}"
    return arr, shape
