"""The sampling session: an excitation through a driver at a fixed period, recorded as it runs.

:func:`run_session` sends one command per slot ``t0 + k T`` (sleeping, then
spinning to the deadline), reads the position that answers it, feeds the
online MRGIA and appends a row to the recording. Per sample it keeps the
scheduled and actual times, the command, the position and a status:

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

The estimator treats every sample it does not use as lost: ``MRGIA.skip(u)``
propagates its model with the command the servo had, and the next used
sample re-primes. The offline stage uses the same samples (:meth:`SessionResult.valid`).

The recording is written as samples arrive, one flushed row each (see
:data:`COLUMNS`), so a crash, a kill or Ctrl-C keeps every sample measured.
For a run of indefinite length (``servoid monitor``) the session can hand
each sample to a callback (``on_sample``) and keep none (``keep_samples=False``):
its memory then stays constant however long it runs.
On Ctrl-C the session stops, switches the torque off and returns what it has
(``result.stopped == "interrupted"``); on a driver error (a servo that stopped
answering, restarted, or left its range) it switches the torque off and
raises the error again, naming the sample and the recording, with the partial
result as ``exc.partial``.

Presentation stays out of here: progress goes to a callback.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from servoid import validation
from servoid.drivers.base import Driver, DriverStats, Measurement
from servoid.drivers.clock import NS_PER_S, Clock, MonotonicClock
from servoid.errors import ConfigError, DriverError, DriverTimeout, EstimatorDiverged, ProtocolError, ServoidError
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.online.mrgia import MRGIA
from servoid.recording import RecordingWriter

__all__ = [
    "Status",
    "Sample",
    "SessionConfig",
    "SessionProgress",
    "SessionResult",
    "run_session",
    "usable",
    "UsableRule",
    "DEFAULT_GUARD_SAMPLES",
    "COLUMNS",
]

log = logging.getLogger("servoid.session")


class Status(str, enum.Enum):
    """What happened to one slot (see the module docstring)."""

    OK = "ok"
    LATE = "late"
    MISSED = "missed"
    TIMEOUT = "timeout"

    def __str__(self) -> str:
        return self.value


#: Columns of a live recording, in order. Times in seconds from the first slot;
#: ``t`` is the scheduled time (what the offline reader uses), ``t_actual`` when
#: the exchange started, ``device_time`` the servo's own clock (unwrapped) when
#: it has one, ``exchange_s`` how long the exchange took. ``reference`` is the
#: excitation, ``u`` the command the servo had (after the command filter and the
#: safety limits), ``y`` the measured position (``nan`` when not measured).
COLUMNS = ("k", "t", "t_actual", "reference", "u", "y", "status", "device_time", "exchange_s", "clamped")


@dataclass(frozen=True)
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
    status : Status
        ok, late, missed or timeout.
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
    status: Status
    device_time: float = math.nan
    exchange_s: float = math.nan
    clamped: bool = False

    def row(self) -> tuple[Any, ...]:
        """The recording row, in the order of :data:`COLUMNS`."""
        return (self.k, self.t_scheduled, self.t_actual, self.reference, self.u, self.y, self.status.value,
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
        if not (status == Status.OK or (self.use_late and status == Status.LATE)):
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
        (:class:`UsableRule`); default, by the driver: 0 for one whose protocol
        carries the slot (``Driver.carries_slots``), else
        :data:`DEFAULT_GUARD_SAMPLES`. :meth:`resolved` fills it in.
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

    def resolved(self, driver: Driver) -> "SessionConfig":
        """This configuration with ``guard_samples`` decided for ``driver``."""
        if self.guard_samples is not None:
            return self
        guard = 0 if driver.carries_slots else DEFAULT_GUARD_SAMPLES
        return dataclasses.replace(self, guard_samples=guard)

    def usable_rule(self) -> UsableRule:
        """A fresh :class:`UsableRule` for this configuration (resolve it first)."""
        return UsableRule(use_late=self.use_late, guard=self.guard_samples or 0)

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
    estimator : MRGIA or None
        The online estimator after the last sample.
    estimator_error : str or None
        Why online estimation stopped early (a divergence), if it did.
    driver_stats : DriverStats
        The driver's counters at the end.
    stopped : str or None
        ``"interrupted"`` after Ctrl-C, else None.
    slot_counts : mapping or None
        Slots per status, counted as they came; set by :func:`run_session`,
        so that a session that kept no samples still reports them.
    """

    samples: tuple[Sample, ...]
    config: SessionConfig
    unit: str
    recording: Path | None
    estimator: MRGIA | None
    estimator_error: str | None
    driver_stats: DriverStats
    stopped: str | None = None
    slot_counts: Mapping[str, int] | None = None
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
        return np.array([s.status.value for s in self.samples])

    @property
    def valid(self) -> np.ndarray:
        """The samples the estimator used (:class:`UsableRule` of the session's configuration)."""
        return usable(self.status, use_late=self.config.use_late, guard=self.config.guard_samples or 0)

    @property
    def counts(self) -> dict[str, int]:
        """Slots per status."""
        if self.slot_counts is not None:
            return dict(self.slot_counts)
        out = {s.value: 0 for s in Status}
        for s in self.samples:
            out[s.status.value] += 1
        return out

    @property
    def late_share(self) -> float:
        """Share of slots not exchanged on time (late, missed or timed out)."""
        return 0.0 if not len(self) else 1.0 - self.counts["ok"] / len(self)

    @property
    def achieved_rate_hz(self) -> float:
        """Exchanges answered per second of the run."""
        if len(self.samples) < 2:
            return math.nan
        answered = sum(s.status in (Status.OK, Status.LATE) for s in self.samples)
        return answered / (self.samples[-1].t_scheduled + self.config.period_s)


def run_session(
    driver: Driver,
    excitation: Iterable[float],
    config: SessionConfig,
    *,
    recording: str | Path | None = None,
    metadata: Mapping[str, Any] | None = None,
    estimator: MRGIA | None = None,
    command_filter: Callable[[float], float] | None = None,
    on_progress: Callable[[SessionProgress], None] | None = None,
    clock: Clock | None = None,
    on_sample: Callable[[Sample], None] | None = None,
    keep_samples: bool = True,
) -> SessionResult:
    """Run ``excitation`` through an open driver, one value per slot.

    Parameters
    ----------
    driver : Driver
        An open driver; the session enables the torque and switches it off at the end.
    excitation : iterable of float
        One reference value per slot (an array, a list, a generator), user unit.
    config : SessionConfig
        Period and policies.
    recording : path, optional
        CSV file to write as samples arrive (:data:`COLUMNS`).
    metadata : mapping, optional
        Extra ``# key: value`` lines for the recording.
    estimator : MRGIA, optional
        Online estimator fed with ``(u, y)`` of the used samples.
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
    config = config.resolved(driver)
    use_clock = clock if clock is not None else getattr(driver, "clock", None)
    if not isinstance(use_clock, Clock):
        use_clock = MonotonicClock()
    sampler = _Sampler(driver, config, use_clock, estimator, command_filter, on_progress, excitation)
    sampler.on_sample, sampler.keep_samples = on_sample, keep_samples
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
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            **(metadata or {}),
        }
        writer = RecordingWriter(recording, COLUMNS, metadata=meta)
    sampler.writer = writer
    try:
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


class _Sampler:
    """The loop of :func:`run_session` and its state."""

    def __init__(
        self,
        driver: Driver,
        config: SessionConfig,
        clock: Clock,
        estimator: MRGIA | None,
        command_filter: Callable[[float], float] | None,
        on_progress: Callable[[SessionProgress], None] | None,
        excitation: Iterable[float],
    ) -> None:
        self.driver, self.config, self.clock = driver, config, clock
        self.estimator = estimator
        self.estimator_error: str | None = None
        self.command_filter, self.on_progress = command_filter, on_progress
        self.total = len(excitation) if hasattr(excitation, "__len__") else None  # type: ignore[arg-type]
        self.samples: list[Sample] = []
        self.counts = {s.value: 0 for s in Status}
        self.usable = config.usable_rule()
        self.writer: RecordingWriter | None = None
        self.stopped: str | None = None
        self.period_ns = int(round(config.period_s * NS_PER_S))
        self.tolerance_ns = int(round(config.late_tolerance_s * NS_PER_S))  # type: ignore[operator]
        self.t0 = 0
        self._shut = False
        self._next_progress = 0
        self._last_device: tuple[int, float] | None = None  # (slot, device time) of the last reading
        self.on_sample: Callable[[Sample], None] | None = None
        self.keep_samples = True
        self.slots = 0

    # ---- the loop -----------------------------------------------------------------
    def run(self, excitation: Iterable[float]) -> None:
        driver, clock, period = self.driver, self.clock, self.period_ns
        if self.estimator is not None:
            _warm_up(self.estimator)
        driver.set_sample_period(self.config.period_s)
        driver.enable()
        give_up_ns = int(self.config.give_up_after_s * NS_PER_S)
        self.t0 = clock.now_ns()
        last_reply = self.t0
        self._next_progress = self.t0
        for k, value in enumerate(excitation):
            reference = float(value)
            if not math.isfinite(reference):
                raise ConfigError(f"excitation[{k}] (={reference!r}) is not finite")
            scheduled = self.t0 + k * period
            if k > 0 and clock.now_ns() - scheduled >= period // 2:
                self._missed(k, scheduled, reference)
                continue
            clock.sleep_until_ns(scheduled)
            if k > 0 and clock.now_ns() - scheduled >= period // 2:
                # the sleep overshot (a loaded host): sent now, the command would reach a servo that runs
                # on its own clock in another sample than its slot, and the record would say otherwise
                self._missed(k, scheduled, reference)
                continue
            command = self.command_filter(reference) if self.command_filter is not None else reference
            start = clock.now_ns()  # after the filter: a slow filter makes the exchange late, and that shows
            try:
                m = driver.exchange(command, slot=k)
            except (DriverTimeout, ProtocolError) as exc:  # this sample is lost; the run goes on
                end = clock.now_ns()
                self._timeout(k, scheduled, start, end, reference, command)
                if end - last_reply > give_up_ns:
                    raise DriverTimeout(
                        f"{driver.describe()} stopped answering: no usable reply for "
                        f"{(end - last_reply) / NS_PER_S:.3g} s (last: {exc})"
                    ) from exc
            else:
                end = clock.now_ns()
                last_reply = end
                self._measured(k, scheduled, start, end, reference, m)
            self._maybe_progress(end)
        self._progress(clock.now_ns())

    def _missed(self, k: int, scheduled: int, reference: float) -> None:
        held = self.driver.last_command
        u = held if held is not None else 0.0  # before any command the servo holds where it was enabled
        self.usable(Status.MISSED)  # arms the guard window
        self._estimate_skip(u)
        self._add(Sample(k, self._s(scheduled), math.nan, reference, u, math.nan, Status.MISSED))

    def _timeout(self, k: int, scheduled: int, start: int, end: int, reference: float, command: float) -> None:
        # whether the servo applied the command is unknown (a lost reply or a lost request); the
        # driver takes a lost reply as the likelier (its last command) and keeps the next command
        # within reach of both
        u = self.driver.last_command
        assert u is not None  # the exchange got as far as sending
        self.usable(Status.TIMEOUT)  # arms the guard window
        self._estimate_skip(u)
        self._add(Sample(k, self._s(scheduled), self._s(start), reference, u, math.nan, Status.TIMEOUT,
                         exchange_s=(end - start) / NS_PER_S, clamped=u != command))  # fmt: skip

    def _measured(self, k: int, scheduled: int, start: int, end: int, reference: float, m: Measurement) -> None:
        # started late, or answered after the next slot began: a device without a clock of its own to
        # show may have taken the reading in a later sample (a host stalled between request and reply)
        late = start - scheduled > self.tolerance_ns or end - scheduled > self.period_ns
        device_time = math.nan if m.device_time is None else float(m.device_time)
        if m.device_time is not None:
            if self._last_device is not None:
                prev_k, prev_t = self._last_device
                expected = (k - prev_k) * self.config.period_s
                # the request reached the device in another sample than its slot (a device clock
                # that counts whole milliseconds may be off by one count without that)
                slack = self.config.period_s / 2 + self.driver.clock_resolution_s
                late = late or abs((device_time - prev_t) - expected) >= slack
            self._last_device = (k, device_time)
        status = Status.LATE if late else Status.OK
        if self.usable(status):
            self._estimate_update(m.command, m.position)
        else:
            self._estimate_skip(m.command)
        self._add(Sample(k, self._s(scheduled), self._s(start), reference, m.command, m.position, status,
                         device_time, (end - start) / NS_PER_S, m.clamped))  # fmt: skip

    # ---- estimator ------------------------------------------------------------------
    def _estimate_update(self, u: float, y: float) -> None:
        if self.estimator is None:
            return
        try:
            self.estimator.update(u, y)
        except EstimatorDiverged as exc:
            self._estimator_failed(exc)

    def _estimate_skip(self, u: float) -> None:
        if self.estimator is not None:
            self.estimator.skip(u)

    def _estimator_failed(self, exc: EstimatorDiverged) -> None:
        # sampling goes on: the recording is what matters, the offline stage re-estimates
        self.estimator_error = str(exc)
        self.estimator = None
        log.warning("online estimation stopped: %s", exc)

    # ---- bookkeeping ----------------------------------------------------------------
    def _s(self, t_ns: int) -> float:
        return (t_ns - self.t0) / NS_PER_S

    def _add(self, sample: Sample) -> None:
        if self.keep_samples:
            self.samples.append(sample)
        self.slots += 1
        self.counts[sample.status.value] += 1
        if self.writer is not None:
            self.writer.append(*sample.row())
        if self.on_sample is not None:
            self.on_sample(sample)

    def _maybe_progress(self, now: int) -> None:
        if self.on_progress is not None and now >= self._next_progress:
            self._progress(now)
            self._next_progress = now + int(self.config.progress_every_s * NS_PER_S)

    def _progress(self, now: int) -> None:
        if self.on_progress is None:
            return
        estimate = None
        if self.estimator is not None:
            est = self.estimator
            names = BacklashModel.parameter_names(est.config.na, est.config.nb)
            values = est.theta.copy()
            values[est.config.na + est.config.nb + 1] += 1.0  # theta holds m2 - 1
            estimate = dict(zip(names, (float(v) for v in values)))
        self.on_progress(SessionProgress(self.slots, self.total, dict(self.counts),
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
            estimator=self.estimator,
            estimator_error=self.estimator_error,
            driver_stats=DriverStats(**vars(self.driver.stats)),
            stopped=self.stopped,
            slot_counts=dict(self.counts),
        )


def _warm_up(estimator: MRGIA) -> None:
    """Compile the estimator's kernels now: a first call inside the loop would stall it for seconds."""
    scratch = MRGIA(estimator.config)
    for u, y in ((0.1, 0.0), (-0.1, 0.05), (0.2, -0.02)):
        scratch.update(u, y)
    scratch.skip(0.0)
    _ = scratch.coverage
