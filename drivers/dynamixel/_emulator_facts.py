"""The emulated Dynamixel's numbers in plain Python: what ``servoid emulate dxl --help`` shows, without NumPy.

:mod:`servoid.drivers.dynamixel.emulated_servo` uses and re-exports them (its
docstring says what they mean for the pseudo-Wiener plant).
"""

from __future__ import annotations

__all__ = ["CURRENT_GAIN", "PWM_GAIN"]

#: Plant input per ampere of goal current in current mode (rad/A).
CURRENT_GAIN = 1.0

#: Plant input per percent of PWM in PWM mode (rad/%).
PWM_GAIN = 0.01
