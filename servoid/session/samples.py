"""What one slot of a session is (:class:`Sample`, its :class:`Status`) and which samples an estimator may use.

:class:`UsableRule` is the one place for that rule: the session applies it to
each sample as it comes and hands the verdict to every listener; a recording
read back later is judged by the same class (:func:`usable`).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from servoid import validation
from servoid.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from servoid.recording import Recording

__all__ = ["Status", "OK", "LATE", "MISSED", "TIMEOUT", "Sample", "JointsSample", "joint_columns", "COLUMNS",
           "UsableRule", "usable", "recording_usable",
           "DEFAULT_GUARD_SAMPLES", "GUARD_AFTER_ANY", "GUARD_AFTER_TIMEOUT", "guard_after"]  # fmt: skip


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

#: :meth:`Sample.line`'s format: the fields in the order of :data:`COLUMNS`.
_LINE = "%d,%s,%s,%s,%s,%s,%s,%s,%s,%d\n"
STATUSES = (OK, LATE, MISSED, TIMEOUT)

#: Columns of a live recording, in order. Times in seconds from the first slot;
#: ``t`` is the scheduled time (what the offline reader uses), ``t_actual`` when
#: the exchange started, ``device_time`` the servo's own clock (unwrapped) when
#: it has one, ``exchange_s`` how long the exchange took. ``reference`` is the
#: excitation, ``u`` the command the servo had (after the command filter and the
#: safety limits), ``y`` the measured position (``nan`` when not measured).
COLUMNS = ("k", "t", "t_actual", "reference", "u", "y", "status", "device_time", "exchange_s", "clamped")


class Sample(NamedTuple):
    """One slot of a session (immutable: a named tuple, which the sampling loop builds in a third of a frozen dataclass's time).

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

    def line(self) -> str:
        """The recording row as one CSV line, the text :meth:`RecordingWriter.append <servoid.recording.RecordingWriter.append>` writes for :meth:`row`.

        One ``%`` format of the tuple itself: the session writes a row per
        sample, and this costs a third less than formatting value by value.
        ``%s`` of a float is its ``repr`` (the shortest text that reads back
        exactly; NumPy's float64 prints the same digits); ``%d`` writes
        ``clamped`` as 0 or 1.
        """
        return _LINE % self


def joint_columns(ids: Sequence[int]) -> tuple[str, ...]:
    """A multi-joint recording's columns: the slot's, then ``reference_<id>, u_<id>, y_<id>, clamped_<id>`` per joint.

    Parameters
    ----------
    ids : sequence of int
        The servo IDs, in the order of the joints.
    """
    per_joint = tuple(f"{name}_{i}" for i in ids for name in ("reference", "u", "y", "clamped"))
    return ("k", "t", "t_actual", "status", "device_time", "exchange_s", *per_joint)


@dataclass(frozen=True, slots=True)
class JointsSample:
    """One slot of a multi-joint session: the slot's times and status, one value per joint for the rest.

    Attributes
    ----------
    k : int
        Slot index.
    t_scheduled, t_actual : float
        Scheduled and actual start of the group exchange, s from slot 0.
    reference, u, y : tuple of float
        Per joint: the excitation, the command the servo had, the measured position (NaN: none).
    status : str
        The slot's status, for every joint.
    device_time : float
        The first joint's device clock (NaN when it has none).
    exchange_s : float
        Duration of the group exchange, s.
    clamped : tuple of bool
        Per joint: whether its limits changed the command.
    """

    k: int
    t_scheduled: float
    t_actual: float
    reference: tuple[float, ...]
    u: tuple[float, ...]
    y: tuple[float, ...]
    status: str
    device_time: float = math.nan
    exchange_s: float = math.nan
    clamped: tuple[bool, ...] = ()

    def row(self) -> tuple[Any, ...]:
        """The recording row, in the order of :func:`joint_columns`."""
        clamped = self.clamped or (False,) * len(self.u)
        per_joint = [v for j in zip(self.reference, self.u, self.y, clamped) for v in (*j[:3], int(j[3]))]
        return (self.k, self.t_scheduled, self.t_actual, self.status, self.device_time, self.exchange_s, *per_joint)

    def joint(self, index: int) -> Sample:
        """Joint ``index``'s view of the slot, as a one-servo :class:`~servoid.session.Sample`.

        Parameters
        ----------
        index : int
            The joint's position in the bus (0 for the first ID).
        """
        clamped = bool(self.clamped[index]) if self.clamped else False
        return Sample(self.k, self.t_scheduled, self.t_actual, self.reference[index], self.u[index], self.y[index],
                      self.status, self.device_time, self.exchange_s, clamped)  # fmt: skip


#: Guard window, in samples, after a sample whose command the servo may not
#: have applied as the recording says (:func:`guard_after`). Measured on the
#: emulated ODrive at 500 Hz, 2000 samples, six runs: a run with 5 late and 6
#: missed slots identified to 1.3e-2 with no guard, 1.4e-4 with 5, 1.3e-5 with
#: 10 and 1.9e-8 with 20 samples; runs without late slots were unaffected (1e-8
#: throughout). On the serial firmware with 0.5 % of the set points corrupted
#: on the way (lost, unanswered): 3.6e-2 without a guard after timeouts,
#: benchmarks/corrupted_commands.py gives the number with it.
DEFAULT_GUARD_SAMPLES = 10

#: The guard follows every unusable sample: for a device on its own clock, a
#: late or skipped command lands in another sample than the recording says.
GUARD_AFTER_ANY: tuple[str, ...] = (LATE, MISSED, TIMEOUT)
#: The guard follows timed-out samples only: for a device told each command's
#: slot, late and skipped slots land where the recording says; but whether a
#: command without an (intact) acknowledgement was applied is unknown on
#: every transport -- the reply or the request may have been lost.
GUARD_AFTER_TIMEOUT: tuple[str, ...] = (TIMEOUT,)


def guard_after(carries_slots: bool) -> tuple[str, ...]:
    """The statuses that open a guard window, for a driver that does (or does not) carry the slot.

    Parameters
    ----------
    carries_slots : bool
        ``Driver.carries_slots`` of the driver.
    """
    return GUARD_AFTER_TIMEOUT if carries_slots else GUARD_AFTER_ANY


class UsableRule:
    """Which samples an estimator may use; one place for the rule, applied in order.

    A sample is usable when its status is ``ok`` (or ``late`` with
    ``use_late``) and it is not within ``guard`` samples after an unusable one
    whose status is in ``after``. The guard covers a command the servo may
    have applied otherwise than the recording says: one that reached a device
    on its own clock late (applied in another sample), or one whose
    acknowledgement never came or came corrupted (lost on the way, or not);
    the samples that follow carry that error until the plant forgets it.

    Parameters
    ----------
    use_late : bool
        Count late samples as usable.
    guard : int
        Samples to leave out after every unusable one (0: none).
    after : sequence of str
        The statuses that open a guard window (:func:`guard_after`; default all).
    """

    def __init__(self, *, use_late: bool = False, guard: int = 0, after: Iterable[str] = GUARD_AFTER_ANY) -> None:
        self.use_late = use_late
        self.guard = validation.integer("guard", guard, minimum=0)
        self.after = frozenset(after)
        unknown = self.after - set(STATUSES)
        if unknown:
            raise ConfigError(f"after (={sorted(unknown)}) must hold statuses among {', '.join(STATUSES)}")
        self._left = 0
        #: No guard window is open: the verdict on an ``ok`` sample is True, and asking the rule for it
        #: changes nothing. A loop that runs per sample may take that verdict without the call while this
        #: holds (the sampling loop does) and ask again after any other status.
        self.settled = True

    def __call__(self, status: str) -> bool:
        """Whether the next sample, of this status, is usable."""
        if not (status == OK or (self.use_late and status == LATE)):
            if status in self.after:
                self._left = self.guard
            self.settled = self._left == 0
            return False
        if self._left > 0:
            self._left -= 1
            self.settled = self._left == 0
            return False
        return True

    def mask(self, statuses: Iterable[str]) -> np.ndarray:
        """The verdicts on ``statuses`` in order, as a boolean array (the rule's state moves on).

        Parameters
        ----------
        statuses : iterable of str
            One status per sample.
        """
        return np.array([self(str(s)) for s in statuses], dtype=np.bool_)


def usable(
    status: Iterable[str], *, use_late: bool = False, guard: int = 0, after: Iterable[str] = GUARD_AFTER_ANY
) -> np.ndarray:
    """Mask of the samples an estimator may use, by :class:`UsableRule` (same parameters)."""
    return UsableRule(use_late=use_late, guard=guard, after=after).mask(status)


def recording_usable(rec: Recording) -> np.ndarray | None:
    """The samples of a recording to identify from: all (None), or for a live recording those its session used.

    The session's own rule, rebuilt from the recording's metadata (``use_late``,
    ``guard_samples``, ``guard_after``), and only samples with a measured ``y``.

    Parameters
    ----------
    rec : Recording
        A recording read from disk; one without a ``status`` column is used whole.
    """
    if rec.status is None:
        return None
    guard = rec.metadata.get("guard_samples", "0")
    guard_samples = int(guard) if guard.isdigit() else 0  # recordings from before the guard have none
    # recordings from before guard_after had the window after every unusable sample
    after = [s for s in rec.metadata.get("guard_after", ",".join(GUARD_AFTER_ANY)).split(",") if s in STATUSES]
    used: np.ndarray = usable(rec.status, use_late=rec.metadata.get("use_late") == "True", guard=guard_samples,
                              after=after)  # fmt: skip
    used &= np.isfinite(rec.y)
    return used
