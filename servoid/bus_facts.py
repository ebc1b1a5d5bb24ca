"""The bus excitation modes in plain Python: what ``servoid identify --help`` shows, without NumPy.

:mod:`servoid.session.joints` uses and re-exports them (a test ties them).
"""

from __future__ import annotations

__all__ = ["MODES", "DEFAULT_MODE", "GENTLE_AMPLITUDE_RAD", "GENTLE_PEAK_ACCEL_RAD_S2"]

#: How the joints of a bus are excited.
MODES = ("sequential", "together")
#: The default (docs/feetech.md says why).
DEFAULT_MODE = "sequential"

#: The bus's default excitation, gentle sines: every servo on a Dynamixel or Feetech bus reads its
#: horn, so its loop closes around the play, and only a set point that decelerates more gently than
#: the load's friction keeps the load on the trailing flank at each reversal (the issue-12 study,
#: Q3: 1-8 rad/s^2; white noise or held steps let the load coast across the play, which then
#: vanishes from the record). Amplitude, rad (``--amplitude`` overrides), and peak acceleration, rad/s^2.
GENTLE_AMPLITUDE_RAD = 0.1
GENTLE_PEAK_ACCEL_RAD_S2 = 8.0
