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

from __future__ import annotations

from typing import TYPE_CHECKING

from servoid import lazy

if TYPE_CHECKING:  # pragma: no cover
    from servoid.excitation.design import Design, Prior, ServoLimits, design
    from servoid.excitation.generate import SignalState, generate, sample, stream
    from servoid.excitation.report import ExcitationReport, InputStats, ModelExcitation, Verdict, assess
    from servoid.excitation.specs import (
        KINDS,
        ChirpSpec,
        GentleSpec,
        LevelsSpec,
        MultisineSpec,
        PRBSSpec,
        SignalSpec,
        StepsSpec,
        UniformSpec,
        format_spec,
        parse_spec,
    )

#: Each public name and the module that defines it, imported when the name is first used.
_EXPORTS: dict[str, str] = {
    "KINDS": "servoid.excitation.specs",
    "SignalSpec": "servoid.excitation.specs",
    "UniformSpec": "servoid.excitation.specs",
    "PRBSSpec": "servoid.excitation.specs",
    "StepsSpec": "servoid.excitation.specs",
    "MultisineSpec": "servoid.excitation.specs",
    "ChirpSpec": "servoid.excitation.specs",
    "LevelsSpec": "servoid.excitation.specs",
    "GentleSpec": "servoid.excitation.specs",
    "parse_spec": "servoid.excitation.specs",
    "format_spec": "servoid.excitation.specs",
    "SignalState": "servoid.excitation.generate",
    "generate": "servoid.excitation.generate",
    "sample": "servoid.excitation.generate",
    "stream": "servoid.excitation.generate",
    "assess": "servoid.excitation.report",
    "ExcitationReport": "servoid.excitation.report",
    "InputStats": "servoid.excitation.report",
    "ModelExcitation": "servoid.excitation.report",
    "Verdict": "servoid.excitation.report",
    "design": "servoid.excitation.design",
    "Design": "servoid.excitation.design",
    "Prior": "servoid.excitation.design",
    "ServoLimits": "servoid.excitation.design",
}

__all__ = [
    "KINDS",
    "SignalSpec",
    "UniformSpec",
    "PRBSSpec",
    "StepsSpec",
    "MultisineSpec",
    "ChirpSpec",
    "LevelsSpec",
    "GentleSpec",
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

lazy.install(__name__, _EXPORTS)
