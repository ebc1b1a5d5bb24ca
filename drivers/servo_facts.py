"""The names and defaults of the servos behind simulated devices, in plain Python.

:mod:`servoid.drivers.servos` owns the servos themselves (the twin presets
with their parameters, the pseudo-Wiener plants) and re-exports these; the
command line's help reads them from here, so that ``servoid CMD --help``
starts without NumPy (``tests/test_startup.py``). A test ties the names to
the presets and plants they stand for.
"""

from __future__ import annotations

__all__ = ["TWIN_NAMES", "MODEL_PLANT_NAMES", "SERVO_NAMES", "DEFAULT_SERVO", "TWIN_AMPLITUDE_RAD", "DEFAULT_RATE_HZ"]

#: The physical twin presets (:data:`servoid.drivers.twin.presets.PRESETS`), in their order.
TWIN_NAMES = ("xm430", "sts3215", "cia402", "odrive")

#: The pseudo-Wiener plants (:data:`servoid.drivers.servos.MODEL_PLANTS`), in their order.
MODEL_PLANT_NAMES = ("model", "paper", "gear")

#: Every name a simulated device's servo may have: the twins, then the pseudo-Wiener plants.
SERVO_NAMES = TWIN_NAMES + MODEL_PLANT_NAMES

#: The servo of a simulated device nobody chose one for (``sim://``, the serial emulator).
DEFAULT_SERVO = "xm430"

#: Half-width of the uniform set point a twin is excited with by default, output rad:
#: several plays of every preset, well inside their travel.
TWIN_AMPLITUDE_RAD = 0.1

#: The sample rate of a live run unless told otherwise (``servoid identify --rate``), Hz; a
#: simulated device that is not told the host's period steps its twin by one period of it.
DEFAULT_RATE_HZ = 200.0
