"""Records with a hidden effect: the known-truth data the discrepancy workflow is tested on.

The paper's plant (Section 4) driven by the paper's uniform white input of
variance 1.93, with one effect of the library added at a given strength and
Gaussian output noise at a given SNR. Tests and the benchmark
(``benchmarks/diagnose_hidden_effects.py``) draw their cases from
:data:`HIDDEN_STRENGTHS`, so both check the same thing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.ident.models.effects import COULOMB_FRICTION, DEAD_ZONE, EXTRA_DELAY, EXTRA_POLE, INPUT_SATURATION, NONE
from servoid.ident.models.extended import AppliedEffect, ExtendedModel, simulate_extended
from servoid.ident.models.simulate import noise_std_for_snr
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE, PAPER_PLANT

__all__ = ["HIDDEN_STRENGTHS", "HiddenRecord", "hidden_effect_record", "hidden_truth"]

#: Two strengths per effect (weak, strong), in the parameter's unit (u = the paper's input, |u| <= 2.41).
#: The extra pole stops at 0.5: beyond ~0.6 the slower plant keeps the paper's backlash (c1 + c2 = 1.5)
#: in its memory zone for more than 90 % of the samples, and no method identifies anything (Remark 2).
HIDDEN_STRENGTHS: dict[str, tuple[float, float]] = {
    COULOMB_FRICTION: (0.1, 0.25),
    INPUT_SATURATION: (1.8, 1.3),
    DEAD_ZONE: (0.2, 0.4),
    EXTRA_DELAY: (1.0, 2.0),
    EXTRA_POLE: (0.3, 0.5),
}


@dataclass(frozen=True)
class HiddenRecord:
    """A simulated record whose plant hides an effect.

    Attributes
    ----------
    truth : ExtendedModel
        The plant: the paper's model plus the hidden effect (or none).
    u, y : ndarray
        Input and noisy output.
    y_clean : ndarray
        Output without noise.
    """

    truth: ExtendedModel
    u: np.ndarray
    y: np.ndarray
    y_clean: np.ndarray


def hidden_truth(effect: str, value: float | None) -> ExtendedModel:
    """The paper's plant with ``effect`` at ``value`` (``"none"``: the plain plant)."""
    if effect == NONE:
        return ExtendedModel(PAPER_PLANT)
    return ExtendedModel(PAPER_PLANT, (AppliedEffect(effect, (float(value),)),))  # type: ignore[arg-type]


def hidden_effect_record(effect: str, value: float | None, *, samples: int, seed: int, snr: float) -> HiddenRecord:
    """Simulate the paper's plant with a hidden effect on the paper's uniform input, with noise at ``snr``."""
    n = validation.integer("samples", samples, minimum=1)
    truth = hidden_truth(effect, value)
    rng = np.random.default_rng(seed)
    u = rng.uniform(-PAPER_INPUT_AMPLITUDE, PAPER_INPUT_AMPLITUDE, size=n)
    y_clean = simulate_extended(truth, u).y
    y = y_clean + rng.normal(0.0, noise_std_for_snr(y_clean, snr), size=n)
    return HiddenRecord(truth=truth, u=u, y=y, y_clean=y_clean)
