"""The sampling loop: one command per slot, each sample stamped, classified and handed to the listeners.

:func:`run_session` sends one command per slot ``t0 + k T`` (sleeping, then
spinning to the deadline), reads the position that answers it, decides once
whether an estimator may use the sample (:class:`~servoid.session.samples.UsableRule`)
and hands the sample with that verdict to every listener
(:mod:`servoid.session.listeners`: the recording, the online estimator, the
monitor, callbacks). Per sample it keeps the scheduled and actual times, the
command, the position and a status:

``ok``
    Exchanged on time.
``late``
    Exchanged, but not at its instant: the exchange started more than
    ``late_tolerance_s`` after its slot, or ended after the next slot began,
    or the device's clock shows the reading more than half a period (plus
    the clock's resolution) away from where the schedule puts it (the
    request reached the device in another sample). The position is
    recorded; the estimator does not use it unless ``use_late`` is set,
    because a reading taken at the wrong instant biases an estimator that
    assumes a fixed period (HARDWARE.md: an ARX fit went from a = 0.975 to
    0.62-0.74 on a few late samples).
``missed``
    The session was half a period or more behind when the slot came (or woke
    up that late from its wait for it), so the slot was skipped rather than
    sent in a burst. Nothing was sent: the servo
    held the previous command, which is what the row's ``u`` says.
``timeout``
    Sent, but no usable reply came in time (none, or a corrupted one); ``u``
    is the command sent, ``y`` unknown. Whether the servo got the command is
    unknown; the session assumes it did (a lost reply) and holds it in the
    slots that follow.

An estimator treats every sample it may not use as lost: ``skip(u)``
propagates its model with the command the servo had, and the next used
sample re-primes. The offline stage uses the same samples (:attr:`SessionResult.valid`,
the verdicts the listeners were given).

The recording is written as samples arrive, one flushed row each (see
:data:`COLUMNS`), so a crash, a kill or Ctrl-C keeps every sample measured.
For a run of indefinite length (``servoid monitor``) the session can keep no
samples (``keep_samples=False``) and leave them to its listeners: its memory
then stays constant however long it runs.
On Ctrl-C the session stops, switches the torque off and returns what it has
(``result.stopped == "interrupted"``); on a driver error (a servo that stopped
answering, restarted, or left its range) it switches the torque off and
raises the error again, naming the sample and the recording, with the partial
result as ``exc.partial``.

Presentation stays out of here: progress goes to a callback.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import chain, count
from pathlib import Path
from typing import Any

import numpy as np

from servoid import validation
from servoid.drivers.base import Driver, DriverStats, Measurement
from servoid.drivers.bus import BusDriver
from servoid.drivers.clock import NS_PER_S, Clock, MonotonicClock
from servoid.drivers.realtime import collector_off_heap, realtime_thread
from servoid.drivers.simulated import SimulatedServo
from servoid.errors import ConfigError, DriverError, DriverTimeout, ProtocolError, ServoidError
from servoid.ident.online.estimator import Estimator
from servoid.recording import RecordingWriter
from servoid.session.listeners import CallbackListener, EstimatorFeed, RecordingListener, SampleListener
from servoid.session.samples import (
    COLUMNS,
    DEFAULT_GUARD_SAMPLES,
    GUARD_AFTER_ANY,
    LATE,
    MISSED,
    OK,
    STATUSES,
    TIMEOUT,
    JointsSample,
    Sample,
    UsableRule,
    guard_after,
    joint_columns,
)

__all__ = ["SessionConfig", "SessionProgress", "SessionResult", "run_session", "BusSampler"]

log = logging.getLogger("servoid.session")


@dataclass(frozen=True, kw_only=True)
class SessionConfig:
    """How a session samples.

    Parameters
    ----------
    period_s : float
        Sample period, seconds.
    late_tolerance_s : float, optional
        An exchange starting more than this after its slot is late; default
        a tenth of the period.
    use_late : bool
        Let the estimator use late samples (default: treat them as lost).
    guard_samples : int, optional
        Samples to leave out after each one that could not be used
        (:class:`UsableRule`); default :data:`DEFAULT_GUARD_SAMPLES`.
    guard_after : sequence of str, optional
        The statuses that open the guard window; default by the driver
        (:func:`~servoid.session.samples.guard_after`): timeouts only for one
        whose protocol carries the slot (``Driver.carries_slots``), every
        unusable status else. :meth:`resolved` fills both in.
    give_up_after_s : float
        Stop with :class:`~servoid.errors.DriverTimeout` when no reply came
        for this long (a servo that stopped answering).
    progress_every_s : float
        Interval of the progress callback.
    """

    period_s: float
    late_tolerance_s: float | None = None
    use_late: bool = False
    guard_samples: int | None = None
    guard_after: tuple[str, ...] | None = None
    give_up_after_s: float = 1.0
    progress_every_s: float = 0.25

    def __post_init__(self) -> None:
        period = validation.positive("period_s", self.period_s)
        object.__setattr__(self, "period_s", period)
        tol = period / 10 if self.late_tolerance_s is None else self.late_tolerance_s
        tol = validation.non_negative("late_tolerance_s", tol)
        if tol >= period / 2:
            raise ConfigError(
                f"late_tolerance_s (={tol!r}) must be below half the period ({period / 2!r} s): "
                "from half a period on, a slot is missed"
            )
        object.__setattr__(self, "late_tolerance_s", tol)
        if self.guard_samples is not None:
            validation.integer("guard_samples", self.guard_samples, minimum=0)
        validation.positive("give_up_after_s", self.give_up_after_s)
        validation.positive("progress_every_s", self.progress_every_s)

    def resolved(self, driver: Driver) -> SessionConfig:
        """This configuration with ``guard_samples`` and ``guard_after`` decided for ``driver``."""
        guard = DEFAULT_GUARD_SAMPLES if self.guard_samples is None else self.guard_samples
        after = guard_after(driver.carries_slots) if self.guard_after is None else tuple(self.guard_after)
        return dataclasses.replace(self, guard_samples=guard, guard_after=after)

    def usable_rule(self) -> UsableRule:
        """A fresh :class:`UsableRule` for this configuration (resolve it first)."""
        after = GUARD_AFTER_ANY if self.guard_after is None else self.guard_after
        return UsableRule(use_late=self.use_late, guard=self.guard_samples or 0, after=after)

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.period_s


@dataclass(frozen=True)
class SessionProgress:
    """What the progress callback receives.

    Attributes
    ----------
    done : int
        Slots so far.
    total : int or None
        Slots in the excitation, when it has a length.
    counts : dict
        Slots per status.
    elapsed_s : float
        Time since slot 0.
    estimate : dict or None
        Current online estimate ``{name: value}`` (None without an estimator).
    """

    done: int
    total: int | None
    counts: Mapping[str, int]
    elapsed_s: float
    estimate: Mapping[str, float] | None

    @property
    def late_share(self) -> float:
        """Share of slots that were not exchanged on time (late, missed or timed out)."""
        return 0.0 if self.done == 0 else 1.0 - self.counts.get("ok", 0) / self.done


@dataclass(frozen=True)
class SessionResult:
    """A finished (or stopped) session.

    Attributes
    ----------
    samples : tuple of Sample
        Every slot, in order.
    config : SessionConfig
        How it was sampled.
    unit : str
        User unit of ``u`` and ``y``.
    recording : Path or None
        Where the recording was written.
    estimator : Estimator or None
        The online estimator after the last sample (None after a divergence).
    estimator_error : str or None
        Why online estimation stopped early (a divergence), if it did.
    driver_stats : DriverStats
        The driver's counters at the end.
    stopped : str or None
        ``"interrupted"`` after Ctrl-C, else None.
    slot_counts : mapping or None
        Slots per status, counted as they came; set by :func:`run_session`,
        so that a session that kept no samples still reports them.
    usable_flags : ndarray of bool or None
        The usable-sample rule's verdict on each kept sample, as the listeners
        got it; set by :func:`run_session`.
    realtime : bool
        Whether the sampling loop ran at ``SCHED_FIFO`` (:mod:`servoid.drivers.realtime`: where the
        system permits it, on the real clock).
    """

    samples: tuple[Sample, ...]
    config: SessionConfig
    unit: str
    recording: Path | None
    estimator: Estimator | None
    estimator_error: str | None
    driver_stats: DriverStats
    stopped: str | None = None
    slot_counts: Mapping[str, int] | None = None
    usable_flags: np.ndarray | None = None
    realtime: bool = False
    _arrays: dict[str, np.ndarray] = field(default_factory=dict, repr=False, compare=False)

    def __len__(self) -> int:
        """Slots run (also when the samples were not kept)."""
        return len(self.samples) if self.slot_counts is None else sum(self.slot_counts.values())

    def _column(self, name: str) -> np.ndarray:
        if name not in self._arrays:
            self._arrays[name] = np.array([getattr(s, name) for s in self.samples], dtype=np.float64)
        return self._arrays[name]

    @property
    def t(self) -> np.ndarray:
        """Scheduled times, seconds."""
        return self._column("t_scheduled")

    @property
    def t_actual(self) -> np.ndarray:
        return self._column("t_actual")

    @property
    def u(self) -> np.ndarray:
        return self._column("u")

    @property
    def y(self) -> np.ndarray:
        return self._column("y")

    @property
    def device_time(self) -> np.ndarray:
        return self._column("device_time")

    @property
    def exchange_s(self) -> np.ndarray:
        return self._column("exchange_s")

    @property
    def status(self) -> np.ndarray:
        return np.array([s.status for s in self.samples])

    @property
    def valid(self) -> np.ndarray:
        """The samples an estimator may use: the verdicts the listeners got (:class:`UsableRule`)."""
        if self.usable_flags is not None:
            return self.usable_flags
        return self.config.usable_rule().mask(self.status)

    @property
    def counts(self) -> dict[str, int]:
        """Slots per status."""
        if self.slot_counts is not None:
            return dict(self.slot_counts)
        out = dict.fromkeys(STATUSES, 0)
        for s in self.samples:
            out[s.status] += 1
        return out

    @property
    def late_share(self) -> float:
        """Share of slots not exchanged on time (late, missed or timed out)."""
        return 0.0 if not len(self) else 1.0 - self.counts["ok"] / len(self)

    def to_dict(self) -> dict[str, Any]:
        """How the session sampled, for JSON: rate asked and answered, slots per status, exchange times, counters.

        The exchange times are null when no exchange was kept (``keep_samples=False``,
        or every slot missed).
        """
        exchange = self.exchange_s[np.isfinite(self.exchange_s)] if self.samples else np.empty(0)
        stats = self.driver_stats
        return {
            "rate_hz": 1.0 / self.config.period_s,
            "samples": len(self),
            "counts": self.counts,
            "late_share": self.late_share,
            "achieved_rate_hz": self.achieved_rate_hz,
            "exchange_median_s": float(np.median(exchange)) if exchange.size else None,
            "exchange_p99_s": float(np.percentile(exchange, 99)) if exchange.size else None,
            "frames_rejected": stats.rejected,
            "replies_stale": stats.stale,
            "commands_unconfirmed": stats.unconfirmed,
            "commands_clamped": stats.clamped,
            "stopped": self.stopped,
            "estimator_error": self.estimator_error,
            "realtime": self.realtime,
        }

    @property
    def achieved_rate_hz(self) -> float:
        """Exchanges answered per second of the run."""
        if len(self.samples) < 2:
            return math.nan
        answered = sum(s.status in (OK, LATE) for s in self.samples)
        return answered / (self.samples[-1].t_scheduled + self.config.period_s)


def run_session(
    driver: Driver | BusDriver,
    excitation: Iterable[float],
    config: SessionConfig,
    *,
    recording: str | Path | None = None,
    metadata: Mapping[str, Any] | None = None,
    estimator: Estimator | None = None,
    command_filter: Callable[[float], float] | None = None,
    on_progress: Callable[[SessionProgress], None] | None = None,
    clock: Clock | None = None,
    on_sample: Callable[[Sample], None] | None = None,
    keep_samples: bool = True,
    listeners: Sequence[SampleListener] = (),
) -> SessionResult:
    """Run ``excitation`` through an open driver, one value per slot.

    Parameters
    ----------
    driver : Driver or BusDriver
        An open driver; the session enables the torque and switches it off at
        the end. A :class:`~servoid.drivers.bus.BusDriver` (several servos of
        one bus) makes it a multi-joint measurement
        (:mod:`servoid.session.joints`): one command per joint per slot, one
        group transaction, one status and one usable verdict per slot for
        every joint, a recording with a column group per joint.
    excitation : iterable of float
        One reference value per slot (an array, a list, a generator), user
        unit; for a bus, one row of one value per joint per slot.
    config : SessionConfig
        Period and policies.
    recording : path, optional
        CSV file to write as samples arrive (:data:`COLUMNS`).
    metadata : mapping, optional
        Extra ``# key: value`` lines for the recording.
    estimator : Estimator, optional
        Online estimator fed with ``(u, y)`` of the usable samples, skipped
        over the others (an :class:`~servoid.session.listeners.EstimatorFeed`).
    command_filter : callable, optional
        ``command = command_filter(reference)`` per slot (a backlash
        compensator's ``step``); default the reference itself.
    on_progress : callable, optional
        Called with a :class:`SessionProgress` every ``config.progress_every_s``
        and once at the end.
    clock : Clock, optional
        Time source; default the driver's own (a simulated servo's virtual
        clock), else the real clock.
    on_sample : callable, optional
        Called with each :class:`Sample` as soon as it is complete (after the
        estimator has seen it). It runs inside the sampling loop: keep it
        short, or the next slots come late.
    keep_samples : bool
        Keep every sample in the result (default). ``False`` keeps none, for
        runs of indefinite length: the result then has the counts but empty
        :attr:`SessionResult.samples` (and no per-sample arrays).
    listeners : sequence of SampleListener
        Further consumers of every sample and its usable verdict, called in
        order after the recording and the estimator (an
        :class:`~servoid.session.listeners.EstimatorFeed` among them also
        feeds the progress line).

    Returns
    -------
    SessionResult

    Raises
    ------
    DriverError
        (or a subclass: DriverTimeout, DeviceRestarted, PositionOutOfRange)
        when the servo failed; the torque is off, the recording is intact, and
        ``exc.partial`` holds the :class:`SessionResult` so far.
    ConfigError
        A non-finite excitation value (named by its slot).
    """
    if not driver.is_open:
        raise DriverError(f"{driver.describe()} is not open: use it as a context manager (with driver: ...)")
    sampler_class: type[_Sampler] = _Sampler
    columns: tuple[str, ...] = COLUMNS
    if isinstance(driver, BusDriver):
        if estimator is not None or command_filter is not None:
            raise ConfigError(
                "estimator= and command_filter= take one servo; for a bus, give each joint's listener in "
                "listeners= (servoid.session.joints.JointFeed)"
            )
        sampler_class, columns = BusSampler, joint_columns(driver.ids)
        metadata = {"joints": ",".join(map(str, driver.ids)), **(metadata or {})}
    config = config.resolved(driver)  # type: ignore[arg-type]
    use_clock = clock
    if use_clock is None:
        use_clock = driver.clock if isinstance(driver, SimulatedServo) else MonotonicClock()
    chain: list[SampleListener] = []
    writer = None
    if recording is not None:
        meta = {
            "servoid recording": "live",
            "source": driver.describe(),
            "unit": driver.position_unit.unit,
            "input_unit": driver.command_unit.unit,
            "period_s": repr(config.period_s),
            "late_tolerance_s": repr(config.late_tolerance_s),
            "use_late": str(config.use_late),
            "guard_samples": str(config.guard_samples),
            "guard_after": ",".join(config.guard_after or GUARD_AFTER_ANY),
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            **(metadata or {}),
        }
        writer = RecordingWriter(recording, columns, metadata=meta)
        chain.append(RecordingListener(writer))
    if estimator is not None:
        chain.append(EstimatorFeed(estimator))
    chain.extend(listeners)
    if on_sample is not None:
        chain.append(CallbackListener(on_sample))
    one: Any = driver  # a Driver, or a BusDriver for the bus sampler
    sampler = sampler_class(one, config, use_clock, chain, command_filter, on_progress, excitation, keep_samples)
    sampler.writer = writer
    # the real clock's slots at SCHED_FIFO where permitted (servoid.drivers.realtime: on a loaded host the
    # scheduler, not the link, spoils them), and the garbage collector off the heap the session starts with (a full
    # collection in any thread holds the interpreter lock the loop needs); a virtual clock keeps no time to be late for
    real = isinstance(use_clock, MonotonicClock)
    realtime = realtime_thread() if real else contextlib.nullcontext(False)
    try:
        with realtime as sampler.realtime, collector_off_heap() if real else contextlib.nullcontext():
            sampler.run(excitation)
    except KeyboardInterrupt:
        sampler.stopped = "interrupted"
    except DriverError as exc:
        sampler.shutdown()
        partial = sampler.result(recording)
        where = f"; the {len(partial)} samples so far are in {partial.recording}" if partial.recording else ""
        message = f"{exc} (stopped at sample {len(partial)}{where})"
        try:
            err = type(exc)(message)  # same type, so callers can still tell a restart from a timeout
        except TypeError:  # a subclass with a richer constructor
            err = DriverError(message)
        err.partial = partial  # type: ignore[attr-defined]
        raise err from exc
    finally:
        sampler.shutdown()
    return sampler.result(recording)


_new_sample = tuple.__new__

#: Values an array excitation hands over at a time as Python floats (one ``tolist`` per chunk instead of
#: a NumPy scalar per sample, which costs its creation and its ``float()``).
_CHUNK = 4096


def _plain(excitation: Iterable[Any]) -> Iterable[Any]:
    """``excitation``'s values in order; an array's as Python objects, converted a chunk at a time."""
    if isinstance(excitation, np.ndarray):
        return chain.from_iterable(excitation[i : i + _CHUNK].tolist() for i in range(0, len(excitation), _CHUNK))
    return excitation


def _not_finite(k: int, value: Any) -> ConfigError:
    return ConfigError(f"excitation[{k}] (={value!r}) is not finite")


class _Sampler:
    """The loop of :func:`run_session` and its state."""

    #: the driver is a bus (:class:`BusSampler`): one measurement per joint per exchange
    _joints = False

    def __init__(
        self,
        driver: Driver,
        config: SessionConfig,
        clock: Clock,
        listeners: list[SampleListener],
        command_filter: Callable[[float], float] | None,
        on_progress: Callable[[SessionProgress], None] | None,
        excitation: Iterable[float],
        keep_samples: bool,
    ) -> None:
        self.driver, self.config, self.clock = driver, config, clock
        self.listeners = listeners
        self.notify = tuple(listener.on_sample for listener in listeners)
        # the estimator whose state the result and the progress line report
        self.feed = next((x for x in listeners if isinstance(x, EstimatorFeed)), None)
        self.command_filter, self.on_progress = command_filter, on_progress
        self.total = len(excitation) if isinstance(excitation, Sequence | np.ndarray) else None
        self.samples: list[Sample] = []
        self.flags: list[bool] = []
        self.counts = dict.fromkeys(STATUSES, 0)
        self.usable = config.usable_rule()
        self.writer: RecordingWriter | None = None
        self.stopped: str | None = None
        self.period_ns = int(round(config.period_s * NS_PER_S))
        self.tolerance_ns = int(round(config.late_tolerance_s * NS_PER_S))  # type: ignore[operator]
        self.t0 = 0
        self._shut = False
        self._next_progress = 0
        self._give_up_ns = int(config.give_up_after_s * NS_PER_S)
        self._period_s = config.period_s
        self.keep_samples = keep_samples
        self._slack_s = config.period_s / 2 + driver.clock_resolution_s
        #: Whether the loop ran at SCHED_FIFO (set by :func:`run_session`).
        self.realtime = False

    # ---- the loop -----------------------------------------------------------------
    def run(self, excitation: Iterable[float]) -> None:
        if self.feed is not None and self.feed.estimator is not None:
            self.feed.estimator.warm_up()
        references = self._values(excitation)  # before the servo moves: an array is checked whole
        self.driver.set_sample_period(self.config.period_s)
        self.driver.enable()
        self.t0 = self.clock.now_ns()
        self._next_progress = self.t0 if self.on_progress is not None else 1 << 62  # never, without a progress call
        self._loop(references)
        self._progress(self.clock.now_ns())

    def _loop(self, references: Iterable[Any]) -> None:
        """The slots, from slot 0 at ``self.t0``, one per reference (:meth:`_values`).

        Its own work is what the session adds to every exchange, so an answered
        slot's status and (for one servo) its sample are made here rather than
        in methods, and the usable rule is asked only while its verdict is not
        settled (:attr:`UsableRule.settled`). A bus's sample
        (:meth:`BusSampler._answered`), missed and timed-out slots go through
        methods.
        """
        clock, period, t0, tolerance = self.clock, self.period_ns, self.t0, self.tolerance_ns
        # bound once: the loop runs per sample
        now, sleep_until, half = clock.now_ns, clock.sleep_until_ns, period // 2
        exchange: Callable[..., Any] = self.driver.exchange  # a bus's answers one measurement per joint
        command_filter, missed, lost = self.command_filter, self._missed, self._lost
        joints, answered = self._joints, self._answered
        rule, counts, notify = self.usable, self.counts, self.notify
        usable, settled = rule.__call__, rule.settled  # __call__: a bound method is quicker
        keep, keep_sample, keep_flag = self.keep_samples, self.samples.append, self.flags.append
        period_s, slack_s, nan, new = self._period_s, self._slack_s, math.nan, _new_sample
        last_k, last_t = -1, nan  # slot and device time of the last reading (-1: none)
        last_reply, next_progress = t0, self._next_progress
        oks = 0  # ok slots not yet in counts (added when the progress or the end reads counts)
        offset = -period  # the slot's time from slot 0, k * period ns: one addition per slot
        try:
            for k, reference in enumerate(references):
                offset += period
                scheduled = t0 + offset
                start = end = sleep_until(scheduled)  # at once when the slot has passed; the time it returned
                behind = start - scheduled
                gave_up: DriverTimeout | None = None
                if behind >= half and k:
                    # half a period behind, or the sleep overshot (a loaded host): sent now, the command would
                    # reach a servo that runs on its own clock in another sample than its slot, and the record
                    # would say otherwise
                    sample = missed(k, scheduled, reference)
                    status = sample.status
                else:
                    if command_filter is None:
                        command = reference
                    else:
                        command = command_filter(reference)
                        start = now()  # after the filter: a slow filter makes the exchange late, and that shows
                        behind = start - scheduled
                    try:
                        m = exchange(command, slot=k)
                    except (DriverTimeout, ProtocolError) as exc:  # this sample is lost; the run goes on
                        end = now()
                        sample, gave_up = lost(exc, k, scheduled, start, end, reference, command, last_reply)
                        status = sample.status
                    else:
                        end = last_reply = now()
                        # late: started late, or answered after the next slot began (a device without a clock
                        # of its own to show may have taken the reading in a later sample: a host stalled between)
                        late = behind > tolerance or end - scheduled > period
                        device_time = m[0].device_time if joints else m.device_time  # a bus: the first joint's
                        if device_time is None:
                            device_time = nan
                        else:
                            device_time = float(device_time)
                            if last_k >= 0:
                                # the request reached the device in another sample than its slot (a device clock
                                # that counts whole milliseconds may be off by one count without that): slack_s
                                late = late or abs((device_time - last_t) - (k - last_k) * period_s) >= slack_s
                            last_k, last_t = k, device_time
                        status = LATE if late else OK
                        if joints:
                            sample = answered(k, scheduled, start, end, reference, m, status, device_time)
                        else:  # tuple.__new__ skips the named tuple's own __new__, a Python frame per sample
                            sample = new(Sample, (k, offset / NS_PER_S, (offset + behind) / NS_PER_S, reference,
                                                  m.command, m.position, status, device_time,
                                                  (end - start) / NS_PER_S, m.clamped))  # fmt: skip
                # the one verdict every listener gets (it arms the guard window), then the listeners in order
                if status is OK and settled:
                    ok = True
                    oks += 1
                else:
                    ok = usable(status)
                    settled = rule.settled
                    counts[status] += 1
                if keep:
                    keep_sample(sample)
                    keep_flag(ok)
                for listener in notify:
                    listener(sample, ok)
                if gave_up is not None:
                    raise gave_up
                if end >= next_progress:
                    counts[OK] += oks
                    oks = 0
                    next_progress = self._maybe_progress(end)
        finally:
            counts[OK] += oks

    def _values(self, excitation: Iterable[Any]) -> Iterable[Any]:
        """The excitation's references in order, checked.

        A one-dimensional array is checked at once (and before the servo moves)
        and handed over as Python floats a chunk at a time; anything else is
        checked value by value as the loop takes it (:meth:`_reference`).
        """
        if isinstance(excitation, np.ndarray) and excitation.ndim == 1:
            values = np.asarray(excitation, dtype=np.float64)
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise _not_finite(int(bad[0]), float(values[bad[0]]))
            return _plain(values)
        return map(self._reference, count(), excitation)

    def _reference(self, k: int, value: Any) -> Any:
        """The excitation's value for slot ``k``, checked."""
        reference = float(value)
        if not math.isfinite(reference):
            raise _not_finite(k, reference)
        return reference

    def _missed(self, k: int, scheduled: int, reference: float) -> Sample:
        held = self.driver.last_command
        u = held if held is not None else 0.0  # before any command the servo holds where it was enabled
        return Sample(k, self._s(scheduled), math.nan, reference, u, math.nan, MISSED)

    def _timeout(self, k: int, scheduled: int, start: int, end: int, reference: float, command: float) -> Sample:
        # whether the servo applied the command is unknown (a lost reply or a lost request); the
        # driver takes a lost reply as the likelier (its last command) and keeps the next command
        # within reach of both
        u = self.driver.last_command
        assert u is not None  # the exchange got as far as sending
        return Sample(k, self._s(scheduled), self._s(start), reference, u, math.nan, TIMEOUT,
                      exchange_s=(end - start) / NS_PER_S, clamped=u != command)  # fmt: skip

    def _answered(self, k: int, scheduled: int, start: int, end: int, reference: Any, m: Any, status: str,
                  device_time: float) -> Any:  # fmt: skip
        """An answered slot's sample, for a bus (:class:`BusSampler`); one servo's is made in :meth:`_loop`."""
        raise NotImplementedError

    def _lost(self, exc: ServoidError, k: int, scheduled: int, start: int, end: int, reference: Any, command: Any,
              last_reply: int) -> tuple[Any, DriverTimeout | None]:  # fmt: skip
        """A timed-out slot's sample, and the error to stop with when no reply came for ``give_up_after_s``."""
        sample = self._timeout(k, scheduled, start, end, reference, command)
        if end - last_reply <= self._give_up_ns:
            return sample, None
        gave_up = DriverTimeout(f"{self.driver.describe()} stopped answering: no usable reply for "
                                f"{(end - last_reply) / NS_PER_S:.3g} s (last: {exc})")  # fmt: skip
        gave_up.__cause__ = exc
        return sample, gave_up

    # ---- bookkeeping ----------------------------------------------------------------
    def _s(self, t_ns: int) -> float:
        return (t_ns - self.t0) / NS_PER_S

    def _maybe_progress(self, now: int) -> int:
        """Call the progress callback when it is due; when it is due next (ns)."""
        if self.on_progress is not None and now >= self._next_progress:
            self._progress(now)
            self._next_progress = now + int(self.config.progress_every_s * NS_PER_S)
        return self._next_progress

    def _progress(self, now: int) -> None:
        if self.on_progress is None:
            return
        estimate = None if self.feed is None else self.feed.current()
        self.on_progress(SessionProgress(sum(self.counts.values()), self.total, dict(self.counts),
                                         (now - self.t0) / NS_PER_S, estimate))  # fmt: skip

    def shutdown(self) -> None:
        """Torque off and close the recording; safe to call twice."""
        if self._shut:
            return
        self._shut = True
        try:
            if self.driver.is_open:
                self.driver.disable()
        except ServoidError as exc:
            log.warning("%s: could not switch the torque off: %s", self.driver.describe(), exc)
        finally:
            if self.writer is not None:
                self.writer.close()

    def result(self, recording: str | Path | None) -> SessionResult:
        return SessionResult(
            samples=tuple(self.samples),
            config=self.config,
            unit=self.driver.position_unit.unit,
            recording=None if recording is None else Path(recording),
            estimator=None if self.feed is None else self.feed.estimator,
            estimator_error=None if self.feed is None else self.feed.error,
            driver_stats=DriverStats(**vars(self.driver.stats)),
            stopped=self.stopped,
            slot_counts=dict(self.counts),
            usable_flags=np.array(self.flags, dtype=np.bool_) if self.keep_samples else None,
            realtime=self.realtime,
        )


class BusSampler(_Sampler):
    """The sampling loop over a :class:`~servoid.drivers.bus.BusDriver`: one :class:`JointsSample` per slot."""

    _joints = True

    def _values(self, excitation: Iterable[Any]) -> Iterable[Any]:
        return map(self._reference, count(), _plain(excitation))  # every row checked for its shape too

    def _reference(self, k: int, value: Any) -> Any:
        reference = np.asarray(value, dtype=np.float64)
        joints = len(self.driver.joints)  # type: ignore[attr-defined]
        if reference.shape != (joints,):
            raise ConfigError(f"excitation[{k}] has shape {reference.shape}; the bus has {joints} joints")
        if not np.all(np.isfinite(reference)):
            raise _not_finite(k, reference.tolist())
        return tuple(float(v) for v in reference)

    def _missed(self, k: int, scheduled: int, reference: Any) -> Any:
        u = tuple(0.0 if held is None else held for held in self.driver.last_command)  # type: ignore[union-attr]
        nan = (math.nan,) * len(u)
        return JointsSample(k, self._s(scheduled), math.nan, reference, u, nan, MISSED)

    def _timeout(self, k: int, scheduled: int, start: int, end: int, reference: Any, command: Any) -> Any:
        bus: Any = self.driver
        u: tuple[float, ...] = tuple(bus.last_command)
        clamped = tuple(a != b for a, b in zip(u, command))
        return JointsSample(k, self._s(scheduled), self._s(start), reference, u, (math.nan,) * len(u),
                            TIMEOUT, exchange_s=(end - start) / NS_PER_S, clamped=clamped)  # fmt: skip

    def _answered(self, k: int, scheduled: int, start: int, end: int, reference: Any, m: Any, status: str,
                  device_time: float) -> Any:  # fmt: skip
        ms: tuple[Measurement, ...] = m
        return JointsSample(k, self._s(scheduled), self._s(start), reference,
                            tuple(x.command for x in ms), tuple(x.position for x in ms), status, device_time,
                            (end - start) / NS_PER_S, tuple(x.clamped for x in ms))  # fmt: skip
