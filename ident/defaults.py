"""The defaults the Python API and the command line share: one owner for each, in plain Python.

The configuration objects (:class:`~servoid.ident.online.mrgia.MRGIAConfig`,
:class:`~servoid.ident.diagnosis.diagnose.DiagnoseConfig`,
:class:`~servoid.ident.monitoring.wear_estimator.WearEstimatorConfig`) take
their field defaults from here, and the command line shows and uses the
same values, so ``MRGIAConfig()`` in a notebook runs what ``servoid
identify`` runs. No NumPy here: ``servoid CMD --help`` reads these without
loading the numerical libraries. The reasons for the numbers stay with the
facts they come from (:mod:`servoid.ident.paper`, the benchmarks named).
"""

from __future__ import annotations

from servoid.ident.paper import RECOMMENDED_RHO_EXPONENT

__all__ = [
    "NA",
    "NB",
    "DELAY",
    "RHO_EXPONENT",
    "EPSILON",
    "DEFAULT_PENALTY",
    "MAX_EFFECTS",
    "REVERSAL_WINDOW",
    "DEFAULT_PROCESS_NOISE",
]

#: Orders and delay of eq. (1): those of the paper's plant (na 2, nb 0, d 1).
NA = 2
NB = 0
DELAY = 1

#: ``r`` in rho(k) = (k+1)^-r: servoid's recommendation, not the paper's 0.25
#: (:data:`servoid.ident.paper.RECOMMENDED_RHO_EXPONENT` says why).
RHO_EXPONENT = RECOMMENDED_RHO_EXPONENT

#: Noise threshold of eqs (37)-(38), unit of y: 0, eqs (35)-(36) (noise-free).
EPSILON = 0.0

#: Relative cut of the validation gap each extra parameter of an effect must buy.
DEFAULT_PENALTY = 0.10

#: Effects the diagnosis adds one after the other.
MAX_EFFECTS = 2

#: Samples after a reversal that count as "just after" in the residuals by regime.
REVERSAL_WINDOW = 5

#: Random-walk variance per update, relative to (c1 + c2)^2 of the servo's
#: model: the trade-off measured in benchmarks/random_walk.py (RMS error 0.006
#: and a lag of ~400 samples on a ramp of c1 + c2 from 1.0 to 1.5 over 200 000
#: samples at SNR 40, steady-state scatter 0.005).
DEFAULT_PROCESS_NOISE = 1e-7
