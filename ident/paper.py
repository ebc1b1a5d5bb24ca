"""The paper's numerical example (Section 4) and its settings: one place for these facts."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.models.pseudo_wiener import BacklashModel

    #: The plant of eq. (46) with m1 = 1, m2 = 1.5, c1 = 0.5, c2 = 1.
    PAPER_PLANT: BacklashModel

__all__ = [
    "PAPER_PLANT",
    "PAPER_INPUT_VARIANCE",
    "PAPER_INPUT_AMPLITUDE",
    "PAPER_SNR",
    "PAPER_RHO_EXPONENT",
    "PAPER_P0",
    "PAPER_SIGMA0",
    "PAPER_REPORTED_MAX_RELATIVE_ERROR",
    "RECOMMENDED_RHO_EXPONENT",
    "paper_theta0",
]

#: Variance of the uniform bounded white-noise input of Section 4.
PAPER_INPUT_VARIANCE = 1.93

#: Half-width of that uniform input: a uniform on [-A, A] has variance A^2 / 3.
PAPER_INPUT_AMPLITUDE = math.sqrt(3.0 * PAPER_INPUT_VARIANCE)

#: Signal-to-noise ratio of the noisy case (sqrt of the output-to-noise variance ratio).
PAPER_SNR = 43.0

#: rho(k) = (k + 1)^-0.25 in Section 4.
PAPER_RHO_EXPONENT = 0.25

#: P(0) = 1e6 I, eq. (31) and Section 4.
PAPER_P0 = 1.0e6

#: Sigma(0) = 1, Section 4.
PAPER_SIGMA0 = 1.0

#: "The maximum relative error of the parameters is 2.62e-2" (noisy case, Section 4).
PAPER_REPORTED_MAX_RELATIVE_ERROR = 2.62e-2

#: servoid's default exponent of rho. With the paper's 0.25 the convergence
#: factor forgets so fast (mu(k) ~ 1 - k^-0.25) that output noise is never
#: averaged out; 0.75 keeps the noise-free convergence and reaches ~10x
#: smaller errors at SNR 43 (see benchmarks/paper_example.py).
RECOMMENDED_RHO_EXPONENT = 0.75


def paper_theta0(na: int, nb: int) -> tuple[float, ...]:
    """theta(0) of Section 4 generalised to any orders: ``b0 = 1``, everything else 0."""
    theta = [0.0] * (na + nb + 4)
    theta[na] = 1.0
    return tuple(theta)


def __getattr__(name: str) -> Any:
    """``PAPER_PLANT``, built on first use: the scalars above are read by the command line's help, which must
    start without NumPy, and the model class needs it."""
    if name == "PAPER_PLANT":
        from servoid.ident.models.pseudo_wiener import BacklashModel

        plant = BacklashModel(a=(0.45, 0.55), b=(0.8,), delay=1, m2=1.5, c1=0.5, c2=1.0)
        globals()[name] = plant
        return plant
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
