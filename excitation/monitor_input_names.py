"""The names of the monitor's steady sines (``servoid monitor --input``) and the cycle's places, without the heavy
imports of their builder.

:mod:`servoid.excitation.monitor_input` builds them and says why each is the default where it is; the CLI's
``--help`` reads only these names (it loads no numerical library).
"""

from __future__ import annotations

__all__ = ["CYCLED_DEFAULT", "CYCLE_STEPS", "CYCLED", "INPUTS", "STEADY"]

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
#: Whether the cycled sine is ``servoid monitor``'s default where the model file's play sits inside the loop: off.
#: It passes issue 15's gate on the benchmark's data files (XM430 9.0-9.3 -> 4.6 %, STS3215 7.2-7.3 -> 3.9-4.0 %,
#: alarms 0.75-2.00 s, 0 false in 10^6), but ``servoid monitor`` runs its own steady sine only for a file with a design
#: (a live ``identify --driver``), and on the twins' live files it moved the XM430's alarm after +20 % from 1.25 to
#: 4.25 s (the window plays correlated, tau 1.0 -> 3.8) and the STS3215's level not at all (docs/monitor.md, moncycle21).
#: N = 2 did not pass either (moncyc2): the XM430 data file's alarm 2.25-3.00 s on 4 of 16 step seeds, and two more
#: live XM430 files read 0.07-0.08x of the play below the steady sine (0.897 / 0.931x against 0.964 / 1.013x).
#: moncyc22: the live XM430's late alarm is the set point's samples beating with the cycle (half-periods of whole
#: samples, :data:`~servoid.excitation.monitor_input.WHOLE_HALVES`, bring it to 1.50 s), but with them the XM430's
#: data file tracks 6.2-6.3 % and its live files read lower still: off (docs/monitor.md).
CYCLED_DEFAULT = False
