"""The names of the monitor's steady sines (``servoid monitor --input``), without the heavy imports of their builder.

:mod:`servoid.excitation.monitor_input` builds them and says why each is the default where it is; the CLI's
``--help`` reads only these names (it loads no numerical library).
"""

from __future__ import annotations

__all__ = ["CYCLED", "INPUTS", "STEADY"]

#: The steady sine after the first fit: one amplitude (the input before moncycle21).
STEADY = "steady"
#: The steady sine whose amplitude cycles over a few places of the loop encoder's count grid.
CYCLED = "cycled"
#: The steady sine's kinds, ``servoid monitor --input``.
INPUTS = (STEADY, CYCLED)
