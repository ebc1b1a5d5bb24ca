"""When to name ``flank_rebound``: the load leaves the flank the motor hits after each reversal (issue 12).

After a reversal the motor crosses the play and hits the far flank; a light load on a lightly damped
gear contact (a servo's horn) bounces off it, is thrown ahead of the motor and comes back. The
massless play operator of the servo-loop model cannot follow that: the load rests on a flank or
moves with it. On the STS3215 twin (the loop closed around the play, encoder on the horn) the horn
rebounds about a quarter of the play and the massless play comes out 6-22 % small at 10-100x the
loop's bandwidth; with the gear's damping x10 (no rebound) the bias is gone (README, "What we
learned"). The fit's quality does not show it (1.2-1.4 times the floor either way), and a model with
the bounce cannot yet give the play's value (ibid.), so the diagnosis names the effect from the
record and the massless fit alone.

The statistic is the massless model's free-run residual ``y - y_hat`` where the effect lives: in the
samples around each departure of the load from a flank. The departures are the model's own (where
its simulated output has come back by :data:`START_SHARE` of its play after a turn: noise-free, so
the alignment does not pick samples by their noise). Each departure's residual is signed by the
direction the load leaves in and the departures are averaged, sample by sample, over
``+- WINDOW_S``; their spread gives each mean a t statistic (departures seconds apart are taken as
independent). A load thrown ahead of the model after the departure makes the mean positive there;
the fit's answer to it (a smaller play: the model leaves earlier) makes it negative nearby. The
effect is named when the swing between the largest mean at or after the departure and the smallest
over the window is at least :data:`MIN_SWING` of the play (and at most :data:`MAX_SWING`: a load
bounces across the play at most), and both are at least :data:`MIN_T` standard errors from zero: a
rebound the record resolves, not a wiggle of its noise.

Measured (issue 12 rebound session; the twins' gentle sines of ``benchmarks/real_servos.py``, seeds
1-3, the answering servo-loop model): STS3215 at 10/20/50x swings 0.16-0.32 of the play, t >= 5 on
both sides; with the gear's damping x10 0.02-0.08. See :func:`rebound` and docs/diagnose.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid.errors import DataError
from servoid.ident.models.effect_names import FLANK_REBOUND
from servoid.ident.offline.intervals import reversal_indices

__all__ = [
    "Rebound",
    "rebound",
    "FLANK_REBOUND",
    "MIN_SWING",
    "MAX_SWING",
    "MIN_T",
    "WINDOW_S",
    "MIN_WINDOW_SAMPLES",
    "START_SHARE",
    "MIN_DEPARTURES",
]

#: The swing of the aligned mean residual, a share of the play, from which the rebound is named: half the
#: twins' rebound (0.24 of the play on the STS3215 twin, 0.17-0.20 on the XM430's).
MIN_SWING = 0.1
#: The largest swing a rebound can make, a share of the play: a load thrown off one flank stops at the other. A
#: larger swing is a model that misses the record around its reversals by more than the play (a servo-loop model
#: fitted to a plant that is not one: the paper's example, 0.67 NRMSE, swings 1.6 of its play), not a bounce.
MAX_SWING = 1.0
#: Standard errors each side of the swing must be from zero (about 30 lags are looked at: 1e-3 each, two-sided,
#: is t 3.3; 4 leaves room for the departures not being quite independent).
MIN_T = 4.0
#: Half the window around each departure, s: the twins' horn bounces for about 20 ms (``benchmarks/horn_turns.py``
#: looks 50 ms after each impact).
WINDOW_S = 0.05
#: The fewest samples each side of a departure (a record sampled slowly, or one without a period).
MIN_WINDOW_SAMPLES = 3
#: How far the model's output must have come back after a turn, a share of its play, to count as a departure.
START_SHARE = 0.1
#: The fewest departures the mean is taken over.
MIN_DEPARTURES = 10


@dataclass(frozen=True)
class Rebound:
    """The residual around the load's departures from a flank: :func:`rebound`'s result.

    Attributes
    ----------
    swing : float
        The largest mean at or after the departure minus the smallest over the window, a share of the play
        (nan without enough departures).
    lead_t, lag_t : float
        The t statistics of those two means (the first positive where the load is thrown ahead).
    lead_s, lag_s : float
        Where they are, s from the departure (samples without a period).
    departures : int
        The departures averaged.
    window : int
        Samples each side of a departure.
    play : float
        The massless model's play, unit of y.
    """

    swing: float
    lead_t: float
    lag_t: float
    lead_s: float
    lag_s: float
    departures: int
    window: int
    play: float

    @property
    def named(self) -> bool:
        """Whether ``flank_rebound`` is named: a swing of :data:`MIN_SWING` to :data:`MAX_SWING`, both sides at :data:`MIN_T`."""
        return bool(
            self.departures >= MIN_DEPARTURES
            and MIN_SWING <= self.swing <= MAX_SWING
            and self.lead_t >= MIN_T
            and self.lag_t <= -MIN_T
        )

    def numbers(self) -> str:
        """The measurement in words: the swing, its t statistics and the departures."""
        return (
            f"the massless model's residual swings by {self.swing:.2f} of its play around the load's departures "
            f"from a flank (t {self.lead_t:+.1f} / {self.lag_t:+.1f}, {self.departures} departures)"
        )

    def reason(self) -> str:
        """The doubt identify adds to a play-in-loop answer where the rebound is named."""
        return (
            f"{FLANK_REBOUND}: the load rebounds off the flank after reversals ({self.numbers()}); the massless "
            "play is biased, small by 6-22 % on the STS3215 twin, and no model here gives the play with the bounce"
        )

    def line(self) -> str:
        """One line for the diagnosis report: named or not, and the numbers."""
        if self.named:
            return f"{FLANK_REBOUND}: the load rebounds off the flank after reversals: {self.numbers()}"
        return f"{FLANK_REBOUND}: not seen; {self.numbers()}"

    def to_dict(self) -> dict[str, Any]:
        """``{"named", "swing", "lead_t", "lag_t", "lead_s", "lag_s", "departures", "window", "play"}`` (nan as None)."""
        values = {"swing": self.swing, "lead_t": self.lead_t, "lag_t": self.lag_t, "lead_s": self.lead_s,
                  "lag_s": self.lag_s}  # fmt: skip
        clean = {k: (float(v) if np.isfinite(v) else None) for k, v in values.items()}
        return {"named": self.named, **clean, "departures": self.departures, "window": self.window, "play": self.play}


def rebound(
    y: np.ndarray,
    y_hat: np.ndarray,
    play: float,
    sample_period_s: float | None = None,
    *,
    valid: np.ndarray | None = None,
) -> Rebound:
    """The massless model's residual around the load's departures from a flank, and whether it names the rebound.

    Parameters
    ----------
    y : ndarray
        The measured load position.
    y_hat : ndarray
        A massless model's free run on the same record (the play operator: the load rests or moves with the motor).
    play : float
        That model's play, unit of y (> 0; otherwise nothing is named).
    sample_period_s : float, optional
        The record's period, s; without it the window is :data:`MIN_WINDOW_SAMPLES` samples.
    valid : ndarray of bool, optional
        The samples that were read (a departure whose window holds a lost one is left out).

    Returns
    -------
    Rebound

    Raises
    ------
    DataError
        ``y`` and ``y_hat`` of different lengths.
    """
    y_arr = np.asarray(y, dtype=np.float64)
    sim = np.asarray(y_hat, dtype=np.float64)
    if y_arr.shape != sim.shape:
        raise DataError(f"y_hat has {sim.size} samples, y {y_arr.size}: expected the free run on the same record")
    period = sample_period_s if sample_period_s is not None and sample_period_s > 0.0 else None
    k = MIN_WINDOW_SAMPLES if period is None else max(MIN_WINDOW_SAMPLES, round(WINDOW_S / period))
    nan = float("nan")
    if not (np.isfinite(play) and play > 0.0) or y_arr.size < 2 * k + 3:
        return Rebound(nan, nan, nan, nan, nan, 0, k, float(play))
    at = reversal_indices(sim, START_SHARE * play)
    at = at[(at - k >= 1) & (at + k < y_arr.size)]
    window = at[:, None] + np.arange(-k, k + 1)[None, :]
    direction = np.sign(sim[at] - sim[at - 1])
    keep = direction != 0
    if valid is not None:
        keep &= np.all(np.asarray(valid, dtype=bool)[window], axis=1)
    at, window, direction = at[keep], window[keep], direction[keep]
    if at.size < max(MIN_DEPARTURES, 2):
        return Rebound(nan, nan, nan, nan, nan, int(at.size), k, float(play))
    residual = y_arr - sim
    aligned = direction[:, None] * residual[window]
    mean = aligned.mean(axis=0)
    spread = aligned.std(axis=0, ddof=1) / np.sqrt(at.size)
    t = np.divide(mean, spread, out=np.zeros_like(mean), where=spread > 0.0)
    lead = k + int(np.argmax(mean[k:]))
    lag = int(np.argmin(mean))
    unit = 1.0 if period is None else period
    return Rebound(
        swing=float((mean[lead] - mean[lag]) / play), lead_t=float(t[lead]), lag_t=float(t[lag]),
        lead_s=(lead - k) * unit, lag_s=(lag - k) * unit, departures=int(at.size), window=k, play=float(play),
    )  # fmt: skip
