"""The simulated CAN drives' numbers in plain Python: what ``servoid emulate can --help`` shows, without NumPy.

:mod:`servoid.drivers.can.sim_cia402` uses and re-exports them.
"""

from __future__ import annotations

__all__ = ["SIM_COUNTS_PER_REV", "SIM_RATED_TORQUE_MNM"]

#: Encoder increments per revolution of the simulated drive with the pseudo-Wiener plant (a 17-bit encoder).
SIM_COUNTS_PER_REV = 1 << 17

#: Rated torque of the simulated drive, mNm (target torque 1000 per mille = 1 Nm).
SIM_RATED_TORQUE_MNM = 1000
