"""Physical servo twins: the servos servoid is measured against (``servoid.drivers.twin``).

A twin is a DC motor with friction that sticks, a gear with play and
stiffness, a load with inertia (and gravity), encoders that quantise, and
the drive's own loops at its own rate on those counts -- nothing in it is
the model servoid fits. Presets hold the numbers of real servos with their
sources (:mod:`servoid.drivers.twin.presets`).

Modules: :mod:`~servoid.drivers.twin.params` (the parameters and their
overrides), :mod:`~servoid.drivers.twin.presets` (sourced presets),
:mod:`~servoid.drivers.twin.kernel` (physics), :mod:`~servoid.drivers.twin.firmware`
(the drives' loops), :mod:`~servoid.drivers.twin.encoder` (quantisation),
:mod:`~servoid.drivers.twin.servo` (the object), :mod:`~servoid.drivers.twin.plant`
(the ``step(u)`` adapter).
"""

from servoid.drivers.twin.params import TwinParams
from servoid.drivers.twin.plant import TwinPlant
from servoid.drivers.twin.presets import preset, preset_names
from servoid.drivers.twin.servo import Twin, TwinCounters, TwinPhysics, TwinReading, TwinRecord, TwinTruth

__all__ = [
    "Twin",
    "TwinParams",
    "TwinPlant",
    "TwinReading",
    "TwinRecord",
    "TwinTruth",
    "TwinCounters",
    "TwinPhysics",
    "preset",
    "preset_names",
]
