"""The seam to the second model structure: the grey-box servo-loop model, fitted when the black box is not enough.

:func:`servoid.ident.identify.identify` fits the paper's pseudo-Wiener model
first. When its fit is at the floor and its residual is white (the paper's
example), nothing can do better and this is skipped (:func:`needed`).
Otherwise the pipeline calls :func:`second_structure`, which fits the
servo-loop model with both places of the play and chooses between them by
validation (:mod:`servoid.ident.offline.loop_fit`, issue 12 part B). Until
that lands it returns None, and the black box is the answer with its verdict.

What the pipeline reads from the result is :class:`LoopResult`, a protocol:
part B's frozen ``LoopChoice`` satisfies it as it is.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["LoopResult", "BlackBox", "needed", "second_structure"]


class LoopResult(Protocol):
    """What :func:`second_structure` returns (part B: ``servoid.ident.offline.loop_fit.LoopChoice``)."""

    @property
    def structure(self) -> str:
        """A name from :mod:`servoid.ident.models.structure_names`."""
        ...

    @property
    def play(self) -> float:
        """The play ``c1 + c2`` in y's units."""
        ...

    @property
    def play_interval(self) -> tuple[float, float]:
        """Its 95 % interval."""
        ...

    @property
    def fit_nrmse(self) -> float:
        """Free-run NRMSE of the chosen structure on the whole record."""
        ...

    @property
    def validation_nrmse(self) -> dict[str, float]:
        """Validation NRMSE per structure name."""
        ...

    @property
    def margin(self) -> float:
        """Relative validation margin of the chosen structure over the other."""
        ...

    @property
    def params(self) -> dict[str, float]:
        """The servo-loop model's parameters."""
        ...

    @property
    def simulated(self) -> np.ndarray:
        """The chosen model's free run over the record."""
        ...

    @property
    def reasons(self) -> tuple[str, ...]:
        """What the fit itself found doubtful (added to the verdict's reasons)."""
        ...


class BlackBox(Protocol):
    """What the seam may read of the black-box result (the pseudo-Wiener fit)."""

    @property
    def model(self) -> BacklashModel:
        """The fitted pseudo-Wiener model (about the operating point)."""
        ...

    @property
    def fit_nrmse(self) -> float:
        """Its free-run NRMSE."""
        ...


def needed(at_floor: bool, white: bool) -> bool:
    """The skip rule: the loop model can only do better when the black box is off the floor or its residual is coloured."""
    return not (at_floor and white)


def second_structure(u: np.ndarray, y: np.ndarray, sample_period_s: float, black_box: BlackBox) -> LoopResult | None:
    """Fit the servo-loop model with both places of the play; None while it is not built (issue 12 part B).

    Parameters
    ----------
    u, y : ndarray
        The record, centred on its operating point, without lost samples.
    sample_period_s : float
        The sample period in seconds (1.0 when the record has no time).
    black_box : BlackBox
        The pseudo-Wiener result (a start, and the comparison).

    Returns
    -------
    LoopResult or None
    """
    return None
