"""Compile hot loops with numba when it is available.

Every kernel in :mod:`servoid.ident` is plain Python over scalars and NumPy
arrays, decorated with :func:`jit`. With numba installed (a dependency of
servoid) the decorator compiles it; ``kernel.py_func`` is always the pure
Python original, which the tests run side by side with the compiled one to
prove both give the same numbers. Without numba (an exotic platform) the
decorator returns the function unchanged and servoid is merely slower.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

_numba: Any
try:  # pragma: no cover - which branch runs depends on the platform
    import numba as _numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    _numba = None
    HAVE_NUMBA = False

__all__ = ["jit", "HAVE_NUMBA", "python_version"]


def jit(func: F) -> F:
    """Compile ``func`` in nopython mode (cached on disk), or return it unchanged."""
    if not HAVE_NUMBA:
        func.py_func = func  # type: ignore[attr-defined]
        return func
    compiled: F = _numba.njit(cache=True, nogil=True)(func)  # a Dispatcher: called as func is
    return compiled


def python_version(kernel: Callable[..., Any]) -> Callable[..., Any]:
    """The uncompiled Python function behind a :func:`jit` kernel."""
    return getattr(kernel, "py_func", kernel)
