"""Excitation signals for identification (``servoid.excitation``).

Bounded, persistently exciting inputs that meet the paper's Remark 2 and
respect a servo's limits: pure, seeded and resumable generators
(:func:`generate`, :func:`sample`, :func:`stream`) of the kinds in
:data:`KINDS`, specified in text as ``kind:key=value,...``
(:func:`parse_spec`); a persistent-excitation report, for the signal alone
or run through a model (:func:`assess`); and a design helper that proposes a
signal from a rough prior and the servo's limits (:func:`design`).

Conventions: ``u`` is in the unit of the command, time in samples,
frequencies in cycles per sample (0 to 0.5).
"""

from servoid.excitation.design import Design, Prior, ServoLimits, design
from servoid.excitation.generate import SignalState, generate, sample, stream
from servoid.excitation.report import ExcitationReport, InputStats, ModelExcitation, Verdict, assess
from servoid.excitation.specs import (
    KINDS,
    ChirpSpec,
    LevelsSpec,
    MultisineSpec,
    PRBSSpec,
    SignalSpec,
    StepsSpec,
    UniformSpec,
    format_spec,
    parse_spec,
)

__all__ = [
    "KINDS",
    "SignalSpec",
    "UniformSpec",
    "PRBSSpec",
    "StepsSpec",
    "MultisineSpec",
    "ChirpSpec",
    "LevelsSpec",
    "parse_spec",
    "format_spec",
    "SignalState",
    "generate",
    "sample",
    "stream",
    "assess",
    "ExcitationReport",
    "InputStats",
    "ModelExcitation",
    "Verdict",
    "design",
    "Design",
    "Prior",
    "ServoLimits",
]
