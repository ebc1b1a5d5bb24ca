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
is not applied. Measured in ``benchmarks/monitor_loop.py``.
"""

from __future__ import annotations

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
    ) -> None:
        if config is None:
            config = WindowConfig(start.sample_period_s, window_s=MONITOR_WINDOW_S, every_s=MONITOR_EVERY_S,
                                  first_s=MONITOR_WINDOW_S)  # fmt: skip
        self.window = WindowRefit(config, start=start, background=background, wait=wait)
        self.alarms = Alarms(bounds, rule)
        self.baseline_s = validation.positive("baseline_s", baseline_s)
        self.events: list[AlarmEvent] = []
        self._seen = 0
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
        rows = self.window.rows()
        if len(rows) == self._seen:
            return
        if math.isnan(self._std):
            base = [r.play for r in rows if r.t_s <= self.baseline_s]
            if rows[-1].t_s <= self.baseline_s or len(base) < 3:
                self._seen = len(rows)
                return
            self._std = float(np.std(base, ddof=1))
        period = self.window.config.sample_period_s
        for row in rows[self._seen :]:
            self.events += self.alarms.check(int(round(row.t_s / period)), {PLAY: (row.play, self._std)})
        self._seen = len(rows)

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
