"""The seam to the second model structure: the grey-box servo-loop model, fitted when the black box is not enough.

:func:`servoid.ident.identify.identify` fits the paper's pseudo-Wiener model
first. When its fit is at the floor and its residual is white (the paper's
example), nothing can do better and this is skipped (:func:`needed`).
Otherwise the pipeline calls :func:`second_structure`, which fits the
servo-loop model with both places of the play and chooses between them by
validation (:func:`servoid.ident.offline.loop_fit.fit_loop`, issue 12 part B).

What the pipeline reads from the result is :class:`LoopResult`, a protocol:
part B's frozen ``LoopChoice`` satisfies it as it is.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["LoopResult", "BlackBox", "needed", "second_structure", "black_box_better"]


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

    @property
    def dead_time_samples(self) -> float | None:
        """The play's dead time at a reversal, in samples, were the play inside the loop (None: not known)."""
        ...

    @property
    def stall_band(self) -> float:
        """The friction stall band ``fs / (kv kp)``, y's units."""
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
    """The skip rule for a record without time: the loop model can only do better when the black box is off the floor or its residual is coloured.

    A record with a sample period comes from a servo, whose play may sit inside its loop: there
    the loop model always runs (:func:`servoid.ident.identify.identify`), because a black box at
    its floor with a white residual can still hold the play in the wrong place -- a play inside
    the loop crossed in less than a sample fits the black box as well as its own structure, with
    another play (the XM430 twin at 5x its bandwidth: +246 %, at the floor, white).
    """
    return not (at_floor and white)


def black_box_better(loop: LoopResult, black_box: BlackBox) -> bool:
    """Whether the black box fits the record clearly better: the servo-loop model's free-run NRMSE is
    more than ``1 + MIN_STRUCTURE_MARGIN`` times the black box's. Then the black box answers; when
    the two fit about equally the servo-loop result answers, so that its margin between the two
    places of the play reaches the verdict (equal fits: undetermined)."""
    from servoid.ident.offline.intervals import MIN_STRUCTURE_MARGIN

    return bool(loop.fit_nrmse > (1.0 + MIN_STRUCTURE_MARGIN) * black_box.fit_nrmse)


def second_structure(
    u: np.ndarray, y: np.ndarray, sample_period_s: float, keep: np.ndarray | None = None
) -> LoopResult | None:
    """Fit the servo-loop model with both places of the play and choose by validation (:func:`fit_loop`).

    Parameters
    ----------
    u, y : ndarray
        The record, centred on its operating point (``y`` is not read where ``keep`` is False).
    sample_period_s : float
        The sample period in seconds (1.0 when the record has no time).
    keep : ndarray of bool, optional
        The readings to score (a live record's validity mask: lost and late samples False); the
        servo-loop model is simulated through the others (:func:`fit_loop`'s ``keep``). Default: all.

    Returns
    -------
    LoopResult or None
        None when the record is too short for the servo-loop model
        (:data:`~servoid.ident.offline.loop_fit.MIN_SAMPLES`). Whether it or the black box
        answers is :func:`black_box_better`'s.
    """
    from servoid.ident.offline.horn_contact import with_horn
    from servoid.ident.offline.loop_fit import MIN_SAMPLES, fit_loop

    if (np.asarray(u).size if keep is None else int(np.count_nonzero(keep))) < MIN_SAMPLES:
        return None
    # where the horn's rebound is named, a light horn on a compliant contact (issue 12)
    return with_horn(u, y, sample_period_s, fit_loop(u, y, sample_period_s, keep=keep, load=None), keep)
