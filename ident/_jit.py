"""Compile hot loops with numba when it is available, and say when a compilation starts.

Every kernel in :mod:`servoid.ident` is plain Python over scalars and NumPy
arrays, decorated with :func:`jit`. With numba installed (a dependency of
servoid) the decorator compiles it; ``kernel.py_func`` is always the pure
Python original, which the tests run side by side with the compiled one to
prove both give the same numbers. Without numba (an exotic platform) the
decorator returns the function unchanged and servoid is merely slower.

Compiled kernels are cached on disk (``cache=True``: ``__pycache__`` beside
the sources, or numba's per-user cache directory where that is not
writable), so only the first run after an install compiles, for some
seconds. :func:`on_first_compile` registers a call made when a compilation
actually starts (numba's ``numba:compile`` event fires on a cache miss only),
so the command line can announce the wait instead of sitting silent. numba
itself is imported at the first :func:`jit`, so that registering costs nothing.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

#: Whether numba is installed (found without importing it).
HAVE_NUMBA = importlib.util.find_spec("numba") is not None

__all__ = ["jit", "jit_inline", "HAVE_NUMBA", "python_version", "on_first_compile", "direct_call"]

#: Called once each, when the first compilation of this process starts.
_hooks: list[Callable[[], None]] = []
_listening = False


def jit(func: F) -> F:
    """Compile ``func`` in nopython mode (cached on disk), or return it unchanged."""
    return _compiled(func)


def jit_inline(func: F) -> F:
    """:func:`jit`, and inlined into every compiled caller (numba's ``inline="always"``).

    For the small helpers of a hot kernel: inlined, a caller that passes
    constants (a kernel specialised for common model orders) lets the
    compiler unroll their loops and fold their offsets, which a call
    across a function boundary hides.
    """
    return _compiled(func, inline="always")


def _compiled(func: F, **options: Any) -> F:
    if not HAVE_NUMBA:
        func.py_func = func  # type: ignore[attr-defined]
        return func
    import numba

    _listen()
    compiled: Any = numba.njit(cache=True, nogil=True, **options)(func)  # a Dispatcher: called as func is
    return compiled  # type: ignore[no-any-return]


def python_version(kernel: Callable[..., Any]) -> Callable[..., Any]:
    """The uncompiled Python function behind a :func:`jit` kernel."""
    return getattr(kernel, "py_func", kernel)


def direct_call(kernel: Callable[..., Any], *example: Any) -> Callable[..., Any]:
    """``kernel`` compiled for the types of ``example``, called without numba's dispatch; else ``kernel``.

    A dispatcher call first works out the types of its arguments and looks the
    compiled version up (about half of a small kernel's cost when it is called
    once per sample from Python). The compiled version's own entry point only
    converts the arguments, so the caller must pass exactly the types of
    ``example`` (C-contiguous float64 arrays stay such arrays, floats stay
    floats); it compiles (or loads from the cache) here if needed. Without
    numba, or where numba does not expose the entry point, this is
    ``kernel`` itself.

    Parameters
    ----------
    kernel : callable
        A :func:`jit` kernel.
    *example : object
        Arguments of the types every later call will pass.
    """
    if not HAVE_NUMBA or not hasattr(kernel, "overloads"):
        return kernel
    from numba import typeof

    try:
        signature = tuple(typeof(a) for a in example)  # type: ignore[no-untyped-call]
        dispatcher: Any = kernel
        dispatcher.compile(signature)
        entry = dispatcher.overloads[signature].entry_point
    except (AttributeError, KeyError, TypeError):  # a numba that keeps its entry points elsewhere
        return kernel
    return entry if callable(entry) else kernel


def on_first_compile(hook: Callable[[], None]) -> None:
    """Call ``hook()`` when a kernel compilation starts (not when one loads from the cache); once.

    Parameters
    ----------
    hook : callable
        Takes no argument; its return value is ignored.
    """
    _hooks.append(hook)


def _listen() -> None:
    global _listening
    if _listening:
        return
    from numba.core import event

    class _FirstCompile(event.Listener):  # numba's listener base, subclassed to hear the first compile
        def on_start(self, ev: Any) -> None:
            while _hooks:
                _hooks.pop(0)()

        def on_end(self, ev: Any) -> None:
            pass

    event.register("numba:compile", _FirstCompile())  # type: ignore[no-untyped-call]
    _listening = True
