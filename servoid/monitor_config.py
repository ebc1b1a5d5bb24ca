"""What ``servoid monitor`` estimates, checks and writes (:class:`MonitorConfig`), and its alarm exit status.

Apart from the monitor's loop (:mod:`servoid.monitor_run`) so that the
command line's help reads these defaults without loading NumPy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.monitoring.alarms import AlarmRule, Bound

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.monitoring.wear_estimator import WearEstimatorConfig

__all__ = ["MonitorConfig", "EXIT_ALARM", "QUANTITIES"]

#: Exit status of ``servoid monitor --fail-on-alarm`` when an alarm was raised.
EXIT_ALARM = 3

#: Quantities the alarm rule watches, as the wear estimator reports them.
QUANTITIES = ("dead_zone", "m2", "fit")


@dataclass(frozen=True, kw_only=True)
class MonitorConfig:
    """What the monitor estimates, checks and writes.

    Parameters
    ----------
    estimator : WearEstimatorConfig
        The servo's model, noise and random-walk settings.
    bounds : tuple of Bound
        Bounds on ``dead_zone`` (``c1 + c2``, output unit), ``m2`` and ``fit``
        (free-run NRMSE); a quantity without a bound is not checked.
    rule : AlarmRule
        Persistence, margin and hysteresis of the alarm rule.
    check_every : int
        Samples between checks of the alarm rule and the compensation.
    row_every : int
        Samples between rows of ``estimates.csv``; a multiple of ``check_every``.
    compensation_step : float
        Relative change of ``c1 + c2`` or ``m2`` since the last written
        compensation that writes a new one (when it holds for ``rule.persist`` checks).
    stop_on_alarm : bool
        End the run at the first alarm raised.
    plot_every_s : float
        Wall-clock seconds between refreshes of the live plot.
    factor : int
        The wear estimator sees every ``factor``-th sample, anti-aliased
        (:class:`~servoid.ident.online.decimate.DecimatingEstimator`): the session samples
        ``factor`` times faster than the rate the model was identified at.
    """

    estimator: WearEstimatorConfig
    bounds: tuple[Bound, ...] = ()
    rule: AlarmRule = AlarmRule()
    check_every: int = 100
    row_every: int = 1000
    compensation_step: float = 0.02
    stop_on_alarm: bool = False
    plot_every_s: float = 5.0
    factor: int = 1

    def __post_init__(self) -> None:
        validation.integer("factor", self.factor, minimum=1)
        check = validation.integer("check_every", self.check_every, minimum=1)
        row = validation.integer("row_every", self.row_every, minimum=1)
        if row % check:
            raise ConfigError(f"row_every (={row}) must be a multiple of check_every (={check}) samples")
        validation.positive("compensation_step", self.compensation_step)
        validation.positive("plot_every_s", self.plot_every_s)
        for b in self.bounds:
            if b.quantity not in QUANTITIES:
                raise ConfigError(f"a bound on {b.quantity!r}: the monitor checks {', '.join(QUANTITIES)}")
        object.__setattr__(self, "bounds", tuple(self.bounds))
