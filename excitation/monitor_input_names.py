"""The names of the monitor's steady sines (``servoid monitor --input``) and the cycle's places, without the heavy
imports of their builder.

:mod:`servoid.excitation.monitor_input` builds them and says why each is the default where it is; the CLI's
``--help`` reads only these names (it loads no numerical library).
"""

from __future__ import annotations

__all__ = ["CYCLE_STEPS", "CYCLED", "INPUTS", "STEADY"]

#: The steady sine after the first fit: one amplitude (the input before moncycle21).
STEADY = "steady"
#: The steady sine whose amplitude cycles over a few places of the loop encoder's count grid.
CYCLED = "cycled"
#: The steady sine's kinds, ``servoid monitor --input``.
INPUTS = (STEADY, CYCLED)
#: Places of the count grid the cycled sine passes (``steps`` of
#: :func:`~servoid.excitation.monitor_input.cycled_sine`): 4 passed issue 15's gate on both horn twins (mongrid20,
#: moncycle21); 3 read the level as well but its 3 s cycle, longer than a window, let the XM430's alarm come 6.75 s
#: late (docs/monitor.md).
CYCLE_STEPS = 4
