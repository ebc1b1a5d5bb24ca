"""The estimator's own plant: a servo that is exactly the pseudo-Wiener model, for exact-recovery tests.

Every simulated device runs it when asked for by name, ``model``
(``sim://model``, ``servoid emulate serial|can|dxl --servo model``; their
default is a physical twin, :mod:`servoid.drivers.servos`): the transports'
exact tests compare what comes through a protocol with its true parameters.

A position-controlled servo with gear backlash, in radians, at the sample
rate of the session: the closed position loop is a linear block with DC gain
1 (poles 0.5 and 0.3, one sample of delay), the gear a backlash with dead
zones of 0.02 rad up and 0.03 rad down and equal slopes (``m2 = 1``).

Why these numbers: the MRGIA converges only while ``|A(e^jw) - 1| < 1`` for
the linear block's denominator (the positive-realness condition of Ljung
1977b that the paper cites); a position loop sampled much faster than its
bandwidth (poles near 1) breaks it. This plant keeps it (margin 0.05), so
the online estimate converges on every transport, and the refinement has
something to refine.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.models.pseudo_wiener import BacklashModel

    #: The bench servo: x(k) = 0.8 x(k-1) - 0.15 x(k-2) + 0.35 u(k-1), backlash 0.02 / 0.03 rad.
    MODEL_PLANT: BacklashModel

__all__ = ["MODEL_PLANT", "MODEL_UNIT", "MODEL_AMPLITUDE"]

#: Unit of the bench servo's command and position.
MODEL_UNIT = "rad"

#: Half-width (rad) of a uniform input that visits every zone of MODEL_PLANT
#: (about 31 % of samples on each line, 38 % in the play).
MODEL_AMPLITUDE = 0.2


def __getattr__(name: str) -> Any:
    """``MODEL_PLANT``, built on first use (the help of ``servoid identify`` reads the amplitude without NumPy)."""
    if name == "MODEL_PLANT":
        from servoid.ident.models.pseudo_wiener import BacklashModel

        plant = BacklashModel(a=(-0.8, 0.15), b=(0.35,), delay=1, m2=1.0, c1=0.02, c2=0.03)
        globals()[name] = plant
        return plant
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
