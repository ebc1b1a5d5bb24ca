"""What one slot of a session is (:class:`Sample`, its :class:`Status`) and which samples an estimator may use.

:class:`UsableRule` is the one place for that rule: the session applies it to
each sample as it comes and hands the verdict to every listener; a recording
read back later is judged by the same class (:func:`usable`).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation

__all__ = ["Status", "OK", "LATE", "MISSED", "TIMEOUT", "Sample", "COLUMNS", "UsableRule", "usable",
           "DEFAULT_GUARD_SAMPLES"]  # fmt: skip


class Status(str, enum.Enum):
    """What happened to one slot (:mod:`servoid.session.sampler` says when each applies).

    Samples carry the plain strings (:data:`OK`, ...; equal to these members):
    the loop compares and counts them per sample, and an enum's ``value``
    lookup there costs more than the comparison itself.
    """

    OK = "ok"
    LATE = "late"
    MISSED = "missed"
    TIMEOUT = "timeout"

    def __str__(self) -> str:
        return self.value


OK, LATE, MISSED, TIMEOUT = "ok", "late", "missed", "timeout"
STATUSES = (OK, LATE, MISSED, TIMEOUT)

#: Columns of a live recording, in order. Times in seconds from the first slot;
#: ``t`` is the scheduled time (what the offline reader uses), ``t_actual`` when
#: the exchange started, ``device_time`` the servo's own clock (unwrapped) when
#: it has one, ``exchange_s`` how long the exchange took. ``reference`` is the
#: excitation, ``u`` the command the servo had (after the command filter and the
#: safety limits), ``y`` the measured position (``nan`` when not measured).
COLUMNS = ("k", "t", "t_actual", "reference", "u", "y", "status", "device_time", "exchange_s", "clamped")


@dataclass(frozen=True, slots=True)
class Sample:
    """One slot of a session.

    Attributes
    ----------
    k : int
        Slot index; scheduled at ``k * period_s``.
    t_scheduled, t_actual : float
        Scheduled and actual start of the exchange, seconds from slot 0
        (``t_actual`` is NaN for a missed slot).
    reference : float
        The excitation's value for this slot.
    u : float
        The command the servo had during the slot, user unit.
    y : float
        Measured position, user unit; NaN when not measured.
    status : str
        ``"ok"``, ``"late"``, ``"missed"`` or ``"timeout"`` (equal to the :class:`Status` members).
    device_time : float
        The device's clock at the reading, seconds (NaN when unknown).
    exchange_s : float
        Duration of the exchange, seconds (NaN for a missed slot).
    clamped : bool
        Whether the safety limits changed the command.
    """

    k: int
    t_scheduled: float
    t_actual: float
    reference: float
    u: float
    y: float
    status: str
    device_time: float = math.nan
    exchange_s: float = math.nan
    clamped: bool = False

    def row(self) -> tuple[Any, ...]:
        """The recording row, in the order of :data:`COLUMNS`."""
        return (self.k, self.t_scheduled, self.t_actual, self.reference, self.u, self.y, self.status,
                self.device_time, self.exchange_s, int(self.clamped))  # fmt: skip


#: Guard window, in samples, after a sample that could not be used, for drivers
#: whose device runs on its own clock (``Driver.carries_slots`` False). Measured
#: on the emulated ODrive at 500 Hz, 2000 samples, six runs: a run with 5 late
#: and 6 missed slots identified to 1.3e-2 with no guard, 1.4e-4 with 5,
#: 1.3e-5 with 10 and 1.9e-8 with 20 samples; runs without late slots were
#: unaffected (1e-8 throughout).
DEFAULT_GUARD_SAMPLES = 10


class UsableRule:
    """Which samples an estimator may use; one place for the rule, applied in order.

    A sample is usable when its status is ``ok`` (or ``late`` with
    ``use_late``) and it is not within ``guard`` samples after one that was
    not. The guard is for devices on their own clock: a command that reached
    such a device late was applied in another sample than the recording says,
    and the following samples carry that error until the plant forgets it.

    Parameters
    ----------
    use_late : bool
        Count late samples as usable.
    guard : int
        Samples to leave out after every unusable one (0: none).
    """

    def __init__(self, *, use_late: bool = False, guard: int = 0) -> None:
        self.use_late = use_late
        self.guard = validation.integer("guard", guard, minimum=0)
        self._left = 0

    def __call__(self, status: str) -> bool:
        """Whether the next sample, of this status, is usable."""
        if not (status == OK or (self.use_late and status == LATE)):
            self._left = self.guard
            return False
        if self._left > 0:
            self._left -= 1
            return False
        return True


def usable(status: Iterable[str], *, use_late: bool = False, guard: int = 0) -> np.ndarray:
    """Mask of the samples an estimator may use, by :class:`UsableRule`."""
    rule = UsableRule(use_late=use_late, guard=guard)
    return np.array([rule(str(s)) for s in status], dtype=np.bool_)
