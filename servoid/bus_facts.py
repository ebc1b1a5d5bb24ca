"""The bus excitation modes in plain Python: what ``servoid identify --help`` shows, without NumPy.

:mod:`servoid.session.joints` uses and re-exports them (a test ties them).
"""

from __future__ import annotations

__all__ = ["MODES", "DEFAULT_MODE"]

#: How the joints of a bus are excited.
MODES = ("sequential", "together")
#: The default (docs/feetech.md says why).
DEFAULT_MODE = "sequential"
