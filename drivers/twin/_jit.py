"""The twin's one import of the compile decorator (so a move of ``servoid.ident._jit`` is a one-line fix here)."""

from servoid.ident._jit import jit

__all__ = ["jit"]
