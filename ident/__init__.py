"""The backlash servo model and its identification (``servoid.ident``).

The pseudo-Wiener model of the paper (Dong, Tan & Tan), its simulator, the
MRGIA online estimator (eqs 17-42), an offline output-error refinement and
the metrics. Depends on NumPy, SciPy and (for speed) numba only.

The rooms, in the order data flows through them::

    models/      what a servo is: the model, theta's layout, simulation, wear, effects
    online/      estimators stepping one sample at a time (the Estimator protocol, the MRGIA)
    offline/     fits over a whole record (output-error refinement, the ARX start)
    identify.py  the pipeline: online estimate, refinement, verdicts
    diagnosis/   where model and measurement disagree, which effect is missing
    monitoring/  following wear: the wear estimator and the alarm rule
    control/     compensating the backlash: inverse, feedforward, tracking study

Conventions: arrays are 1-D float64, one entry per sample, oldest first;
time is counted in samples; ``u`` is in the unit of the command and ``y``,
``x``, ``c1``, ``c2`` in the unit of the measured position.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from servoid import lazy

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.identify import Identification, check_record, identify
    from servoid.ident.metrics import nrmse
    from servoid.ident.models.plant import Plant
    from servoid.ident.models.pseudo_wiener import M1, BacklashModel, ThetaLayout
    from servoid.ident.models.simulate import Simulation, free_run, noise_std_for_snr, simulate
    from servoid.ident.offline.refine import Refinement, arx_start, refine
    from servoid.ident.online.estimator import Estimator
    from servoid.ident.online.mrgia import (
        MRGIA,
        MRGIAConfig,
        MRGIAResult,
        RecoveryEvent,
        Step,
        convergence_margin,
        noise_epsilon,
        run_mrgia,
    )
    from servoid.ident.paper import PAPER_PLANT

#: Each public name and the module that defines it, imported when the name is first used.
_EXPORTS: dict[str, str] = {
    "BacklashModel": "servoid.ident.models.pseudo_wiener",
    "M1": "servoid.ident.models.pseudo_wiener",
    "ThetaLayout": "servoid.ident.models.pseudo_wiener",
    "Estimator": "servoid.ident.online.estimator",
    "PAPER_PLANT": "servoid.ident.paper",
    "Simulation": "servoid.ident.models.simulate",
    "simulate": "servoid.ident.models.simulate",
    "free_run": "servoid.ident.models.simulate",
    "noise_std_for_snr": "servoid.ident.models.simulate",
    "Plant": "servoid.ident.models.plant",
    "MRGIA": "servoid.ident.online.mrgia",
    "MRGIAConfig": "servoid.ident.online.mrgia",
    "MRGIAResult": "servoid.ident.online.mrgia",
    "RecoveryEvent": "servoid.ident.online.mrgia",
    "Step": "servoid.ident.online.mrgia",
    "run_mrgia": "servoid.ident.online.mrgia",
    "noise_epsilon": "servoid.ident.online.mrgia",
    "convergence_margin": "servoid.ident.online.mrgia",
    "Refinement": "servoid.ident.offline.refine",
    "refine": "servoid.ident.offline.refine",
    "arx_start": "servoid.ident.offline.refine",
    "Identification": "servoid.ident.identify",
    "identify": "servoid.ident.identify",
    "check_record": "servoid.ident.identify",
    "nrmse": "servoid.ident.metrics",
}

__all__ = [
    "BacklashModel",
    "M1",
    "ThetaLayout",
    "Estimator",
    "PAPER_PLANT",
    "Simulation",
    "simulate",
    "free_run",
    "noise_std_for_snr",
    "Plant",
    "MRGIA",
    "MRGIAConfig",
    "MRGIAResult",
    "RecoveryEvent",
    "Step",
    "run_mrgia",
    "noise_epsilon",
    "convergence_margin",
    "Refinement",
    "refine",
    "arx_start",
    "Identification",
    "identify",
    "check_record",
    "nrmse",
]

lazy.install(__name__, _EXPORTS)
