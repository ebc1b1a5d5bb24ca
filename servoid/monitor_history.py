"""The estimates of a monitoring run over its whole length, in constant memory, and their snapshot for plots.

Apart from the monitor's loop (:mod:`servoid.monitor_run`) so that the plots
(:mod:`servoid.plots.monitor`) can read a snapshot without importing the loop
that draws them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.ident.monitoring.alarms import AlarmEvent, Bound

__all__ = ["HISTORY_COLUMNS", "HistorySnapshot", "MonitorHistory"]


#: Columns of :class:`MonitorHistory`, the series the plot draws.
HISTORY_COLUMNS = ("k", "t", "dead_zone", "dead_zone_std", "m2", "m2_std", "fit", "true_dead_zone", "true_m2")


@dataclass(frozen=True)
class HistorySnapshot:
    """A copy of the history for plotting (picklable: it crosses to the plotting process).

    Attributes
    ----------
    rows : ndarray, shape (n, len(HISTORY_COLUMNS))
        The kept rows, oldest first.
    alarms : tuple of (str, int, int or None)
        ``(label, raised at sample, cleared at sample or None)`` per alarm.
    bounds : tuple of Bound
        The bounds checked.
    unit : str
        Output unit.
    source : str
        What was monitored.
    period_s : float
        Sample period, seconds (``t = k period_s``).
    """

    rows: np.ndarray
    alarms: tuple[tuple[str, int, int | None], ...]
    bounds: tuple[Bound, ...]
    unit: str
    source: str
    period_s: float

    def column(self, name: str) -> np.ndarray:
        return self.rows[:, HISTORY_COLUMNS.index(name)]


class MonitorHistory:
    """The estimates over the whole run in constant memory: when full, every other row is dropped.

    Parameters
    ----------
    capacity : int
        Rows kept at most (even); the spacing of the kept rows doubles each
        time it fills, so they always span the whole run.
    """

    def __init__(self, capacity: int = 2048, *, max_alarms: int = 200) -> None:
        self.capacity = validation.integer("capacity", capacity, minimum=2) // 2 * 2
        self._rows = np.full((self.capacity, len(HISTORY_COLUMNS)), np.nan)
        self._n = 0
        self._stride = 1
        self._offered = 0
        self._max_alarms = max_alarms
        self._alarms: list[list[Any]] = []

    def add(self, values: Mapping[str, float]) -> None:
        """Offer one row (every offered row at the current spacing is kept)."""
        keep = self._offered % self._stride == 0
        self._offered += 1
        if not keep:
            return
        if self._n == self.capacity:
            self._rows[: self.capacity // 2] = self._rows[::2]
            self._rows[self.capacity // 2 :] = np.nan
            self._n = self.capacity // 2
            self._stride *= 2
            if (self._offered - 1) % self._stride:
                return
        self._rows[self._n] = [values.get(c, math.nan) for c in HISTORY_COLUMNS]
        self._n += 1

    def alarm(self, event: AlarmEvent) -> None:
        """Note an alarm raised or cleared, for the plot's shading."""
        label = event.bound.label
        if event.raised:
            self._alarms.append([label, event.since, None])
            del self._alarms[: max(0, len(self._alarms) - self._max_alarms)]
        else:
            for entry in reversed(self._alarms):
                if entry[0] == label and entry[2] is None:
                    entry[2] = event.sample
                    break

    def __len__(self) -> int:
        return self._n

    def snapshot(self, *, bounds: tuple[Bound, ...], unit: str, source: str, period_s: float) -> HistorySnapshot:
        """A copy of the kept rows and alarms."""
        alarms = tuple((str(a[0]), int(a[1]), a[2]) for a in self._alarms)
        return HistorySnapshot(self._rows[: self._n].copy(), alarms, bounds, unit, source, period_s)
