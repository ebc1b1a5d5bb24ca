"""Following the wear of a play inside the loop: the servo-loop model's window refit with the alarm rule on its play.

The wear estimator (:mod:`~servoid.ident.monitoring.wear_estimator`) is the
MRGIA in random-walk mode: it tracks the pseudo-Wiener model only. For a
model whose play sits in the loop (``play_in_loop``), or wherever the
servo-loop model is the structure, :class:`LoopWearTracker` runs the same
moving-window refit as live identification
(:class:`~servoid.ident.online.window.WindowRefit`, started from the model
file's loop, so no fit from scratch) and applies the monitor's alarm rule
(:class:`~servoid.ident.monitoring.alarms.Alarms`) to the play at each refit.

The play's standard deviation, which the rule's margin needs, is the scatter
of the window plays over the first ``baseline_s`` of monitoring (the estimate's
own noise on the servo as it was when monitoring began); before that the rule
is not applied. With ``rebase`` the bounds on the play are then moved to the
median of those plays (``servoid monitor``'s ``--dead-zone P%``). Measured in ``benchmarks/monitor_loop.py``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from servoid import validation
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.monitoring.alarms import AlarmEvent, AlarmRule, Alarms, Bound
from servoid.ident.online.window import WindowConfig, WindowRefit, WindowResult

__all__ = ["LoopWearTracker", "PLAY", "BASELINE_S", "MONITOR_WINDOW_S", "MONITOR_EVERY_S"]

#: The quantity name of the play in the alarm rule's readings and bounds.
PLAY = "dead_zone"
#: Servo seconds of monitoring whose window plays give the estimate's scatter.
BASELINE_S = 20.0
#: The monitor's window and refit period, servo s: shorter than identify's (30 s, 5 s) to
#: follow wear, long enough to hold reversals of a working servo's motion.
MONITOR_WINDOW_S = 10.0
MONITOR_EVERY_S = 1.0


class LoopWearTracker:
    """An :class:`~servoid.ident.online.estimator.Estimator` that follows the play of a servo-loop model and raises alarms.

    Parameters
    ----------
    start : ServoLoopModel
        The model the monitor starts from (a model file's loop).
    bounds : sequence of Bound
        The alarm bounds; the play's quantity is :data:`PLAY`.
    rule : AlarmRule, optional
        The alarm rule (default: the monitor's).
    config : WindowConfig, optional
        Window and refit period (default :data:`MONITOR_WINDOW_S`, :data:`MONITOR_EVERY_S`, at the start's period).
    baseline_s : float
        Servo seconds whose window plays give the scatter.
    background, wait : bool
        As :class:`~servoid.ident.online.window.WindowRefit`.
    rebase : bool
        Scale the bounds on the play, once the baseline is known, by the median baseline play
        over the start's play: a bound given as a share of the model file's play then holds
        around the play the windows see on this servo (its structure's bias is the same in
        every window, and an alarm on wear must not see it; ``benchmarks/monitor_loop.py``'s
        rule). The scaled bounds are :attr:`bounds`.
    """

    def __init__(
        self,
        start: ServoLoopModel,
        bounds: Sequence[Bound],
        rule: AlarmRule | None = None,
        config: WindowConfig | None = None,
        *,
        baseline_s: float = BASELINE_S,
        background: bool = True,
        wait: bool = False,
        rebase: bool = False,
    ) -> None:
        if config is None:
            config = WindowConfig(start.sample_period_s, window_s=MONITOR_WINDOW_S, every_s=MONITOR_EVERY_S,
                                  first_s=MONITOR_WINDOW_S)  # fmt: skip
        self.window = WindowRefit(config, start=start, background=background, wait=wait)
        self.alarms = Alarms(bounds, rule)
        self.bounds = tuple(bounds)
        self._rule = rule
        self._rebase = bool(rebase)
        self._start_play = start.play
        self.baseline_s = validation.positive("baseline_s", baseline_s)
        self.events: list[AlarmEvent] = []
        self._seen = 0
        self._baseline: list[float] = []
        self._std = math.nan

    def update(self, u: float, y: float) -> None:
        """Take a measured sample."""
        self.window.update(u, y)
        self._check()

    def skip(self, u: float) -> None:
        """Take a sample whose measurement is not to be used."""
        self.window.skip(u)
        self._check()

    def _check(self) -> None:
        new = self.window.rows_since(self._seen)  # per sample: only the refits not seen yet are copied
        if not new:
            return
        if math.isnan(self._std):
            self._baseline += [r.play for r in new if r.t_s <= self.baseline_s]
            if new[-1].t_s <= self.baseline_s or len(self._baseline) < 3:
                self._seen += len(new)
                return
            self._std = float(np.std(self._baseline, ddof=1))
            if self._rebase and self._start_play > 0.0:
                scale = float(np.median(self._baseline)) / self._start_play
                self.bounds = tuple(
                    dataclasses.replace(b, low=b.low * scale, high=b.high * scale) if b.quantity == PLAY else b
                    for b in self.bounds
                )
                self.alarms = Alarms(self.bounds, self._rule)
        period = self.window.config.sample_period_s
        for row in new:
            self.events += self.alarms.check(int(round(row.t_s / period)), {PLAY: (row.play, self._std)})
        self._seen += len(new)

    @property
    def std(self) -> float:
        """The play's scatter over the baseline (NaN before it is known)."""
        return self._std

    def warm_up(self) -> None:
        """Compile the servo-loop simulation now."""
        self.window.warm_up()

    def current(self) -> Mapping[str, float]:
        """The last refit's play and loop gains, with the play's scatter."""
        now = dict(self.window.current())
        return {**now, "play_std": self._std} if now else now

    def result(self) -> WindowResult:
        """Wait for a running refit, check it, and stop the worker (no extra final window)."""
        out = self.window.result(final=False)
        self._check()
        return out
