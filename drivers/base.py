"""The driver base class: what every servo driver shares.

A driver talks to one servo. It implements a handful of primitives; this base
class does the rest, once, for every driver.

What a driver MUST implement
----------------------------
``_open(self) -> None``
    Acquire the transport (port, bus, SDK handle) and check the servo answers.
``_close(self) -> None``
    Release the transport. Called once, after torque was switched off.
``_set_torque(self, enabled: bool) -> None``
    Switch the servo's output stage on or off (Dynamixel Torque Enable, CiA 402
    state machine, the serial firmware's enable request, ...).
``_exchange(self, command: float, slot: int | None) -> Reading``
    Send one command, in the driver's native unit, and return the measurement
    that answers it (position in native units, with the device's clock when it
    has one). One call per sample. ``slot`` is the sampling session's slot
    number ``k`` of the sample (scheduled at ``t0 + k T``; None outside a
    session), for devices that want to know how many periods lie between two
    commands.

What a driver MAY implement
---------------------------
``_read(self) -> Reading``
    A measurement without a command (the base raises if absent).
``_identity(self) -> dict``
    What the servo says it is (model, firmware, serial number, id), stored in
    ``model.json``.
``_set_period(self, period_s: float) -> None``
    Told by :meth:`Driver.set_sample_period` (the sampling session calls it
    before enabling) the period at which exchanges will come. Devices whose
    control loop or simulated plant runs on its own time grid use it (the
    serial firmware's control period, the simulated servo's sample instants,
    a CAN SYNC period); the default ignores it.
``scheme`` / ``options`` (class attributes)
    The URL scheme the registry maps to this class, and the URL options it
    accepts (:class:`Option`); the base adds ``min``, ``max``, ``max_step``.
``clock_wrap_s`` (class attribute)
    Period after which the device clock wraps (a u32 microsecond counter wraps
    after 4294.967296 s, the Dynamixel tick after 32.768 s); the base unwraps.
``clock_resolution_s`` (class attribute)
    Resolution of the device clock, seconds (the Dynamixel tick counts whole
    milliseconds); the sampling session widens its check of the device's
    timing by it, so that the tick's rounding alone never makes a sample late.
``carries_slots`` (class attribute)
    True when the protocol tells the device which sample slot each command
    belongs to (the serial firmware's ``S <counts> <slot>``, CiA 402's SYNC
    counter, the simulated servo), so that a late exchange cannot shift the
    device's input sequence. A device on its own clock (ODrive, Dynamixel)
    applies a late command in a later sample than the recording says, and
    the samples after it carry that error for a few periods; for such
    drivers (the default) the sampling session leaves a guard window after
    every sample it could not use (:class:`servoid.session.UsableRule`).
``watchdog_s`` (instance attribute, set in ``__init__``)
    The device's own watchdog as the driver configures it: seconds without
    a request after which the servo switches itself off (or stops) -- what
    covers a host killed with SIGKILL, a crash or a cut cable; None when the
    device has none or it is off. The base refuses a sample period that would
    let it expire between two samples (:meth:`Driver.set_sample_period`).
``watchdog_fed_by_exchanges`` (class attribute)
    True (the default) when the exchanges themselves feed the device's
    watchdog, so that the sample period must stay below half of it; False
    when something else does (CiA 402's heartbeat, sent by a thread).
``command_step`` (instance attribute, set in ``__init__`` or ``_open``)
    The smallest change of the command the device can apply, in native units
    (1 for a goal in whole encoder counts); None (the default) for a
    continuous command. The base rounds every command to it, never past a
    limit, before ``_exchange`` sees it, and reports the rounded command as
    the one sent: what the servo got, to identify from (the rounding is
    otherwise an input error of up to half a step).
``readings_side`` (instance attribute, set in ``__init__``)
    Which shaft the position readings are of (:mod:`servoid.readings_side`):
    ``"output"`` (the default) or ``"motor"`` (an ODrive's own encoder). The
    base adds it to :attr:`Driver.identity` (so to ``model.json`` and the
    recording's metadata); identification reads it: the play between motor
    and output is not in a record read on the motor.
``from_url(cls, url)``
    Only if the defaults (options parsed into keyword arguments) do not fit.

What the base class owns
------------------------
Unit conversion (native <-> the user's unit, stated in :class:`UnitConversion`),
rounding of commands to the device's resolution (:meth:`Driver.quantise`),
safety limits (a command outside the position range, farther than
``amplitude`` from ``centre`` or changing faster than ``max_step`` per sample
is clamped and counted, never sent; a measured position farther than
``guard`` outside the range stops the run with the torque off), the last
command sent and which commands the servo may hold (:attr:`Driver.last_command`,
:attr:`Driver.possibly_held`: after a lost reply or a lost request the servo
holds either the new command or the one before, and the next command is kept
within ``max_step`` of both), the context
manager, idempotent :meth:`Driver.close` that always tries to leave the torque
off (and holds Ctrl-C, SIGTERM and SIGHUP until it has: a second Ctrl-C
cannot cut the torque-off short), unwrapping of the device clock, counters, and wrapping of library errors
into :mod:`servoid.errors` (``raise ... from``): a ``TimeoutError`` becomes
:class:`DriverTimeout`, anything else :class:`DriverError`.

Drivers are not thread-safe; a driver belongs to the thread that opened it.
"""

from __future__ import annotations

import abc
import contextlib
import logging
import math
import signal
import threading
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from types import FrameType
from typing import Any, ClassVar

from servoid import readings_side, validation
from servoid.errors import ConfigError, DriverError, DriverTimeout, PositionOutOfRange, ServoidError

__all__ = [
    "Driver",
    "Reading",
    "Measurement",
    "PendingCommand",
    "Limits",
    "UnitConversion",
    "Option",
    "DriverStats",
    "DriverURL",
]

log = logging.getLogger("servoid.drivers")


@dataclass(frozen=True)
class UnitConversion:
    """A linear map between a driver's native unit and the user's unit.

    ``user = (native - offset) * scale`` and ``native = user / scale + offset``.

    Parameters
    ----------
    unit : str
        Name of the user's unit (``"rad"``, ``"counts"``, ``"A"``, ...).
    scale : float
        User units per native unit (``2 pi / 4096`` rad per count for a
        4096-count encoder), nonzero.
    offset : float
        Native value that maps to user zero (``2048`` counts for a Dynamixel's
        centre position).
    """

    unit: str = "unit"
    scale: float = 1.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        scale = validation.real("scale", self.scale)
        if scale == 0.0:
            raise ConfigError("scale (=0.0) must be nonzero")
        validation.real("offset", self.offset)

    def to_user(self, native: float) -> float:
        return (native - self.offset) * self.scale

    def to_native(self, user: float) -> float:
        return user / self.scale + self.offset


@dataclass(frozen=True)
class Limits:
    """Safety limits on the command, in the user's unit.

    Parameters
    ----------
    minimum, maximum : float
        Allowed command range (the servo's safe position range, or a band
        ``centre +/- amplitude`` around an operating point).
    max_step : float
        Largest change of the command from one sample to the next (a rate
        limit: ``max_step / sample_period`` per second).
    amplitude : float
        Largest distance of the command from ``centre`` (an amplitude clamp,
        for an excitation around an operating point); the command range is
        the intersection of ``[minimum, maximum]`` and
        ``[centre - amplitude, centre + amplitude]``.
    centre : float
        Operating point the amplitude is measured from.
    guard : float
        How far the *measured* position may lie outside the command range
        before the run is stopped: a reading beyond it raises
        :class:`~servoid.errors.PositionOutOfRange` after switching the torque
        off (a slipping coupling, a wrong unit, a runaway). Infinite (off) by
        default; only meaningful with a finite range.
    """

    minimum: float = -math.inf
    maximum: float = math.inf
    max_step: float = math.inf
    amplitude: float = math.inf
    centre: float = 0.0
    guard: float = math.inf

    def __post_init__(self) -> None:
        for name in ("minimum", "maximum", "max_step", "amplitude", "centre", "guard"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
                raise ConfigError(f"{name} (={value!r}) must be a number")
        if not self.minimum < self.maximum:
            raise ConfigError(f"minimum (={self.minimum!r}) must be < maximum (={self.maximum!r})")
        if not self.max_step > 0:
            raise ConfigError(f"max_step (={self.max_step!r}) must be > 0")
        if not self.amplitude > 0:
            raise ConfigError(f"amplitude (={self.amplitude!r}) must be > 0")
        if not math.isfinite(self.centre):
            raise ConfigError(f"centre (={self.centre!r}) must be finite")
        if not self.guard >= 0:
            raise ConfigError(f"guard (={self.guard!r}) must be >= 0")
        if not self.low < self.high:
            raise ConfigError(
                f"centre +/- amplitude (={self.centre!r} +/- {self.amplitude!r}) lies outside "
                f"[minimum, maximum] = [{self.minimum!r}, {self.maximum!r}]"
            )

    @property
    def low(self) -> float:
        """Lowest command sent: the range and the amplitude band together."""
        return max(self.minimum, self.centre - self.amplitude)

    @property
    def high(self) -> float:
        """Highest command sent."""
        return min(self.maximum, self.centre + self.amplitude)

    def window(self, held: tuple[float, float] | None) -> tuple[float, float]:
        """The commands allowed next, ``(low, high)``: inside the range and within ``max_step`` of every held one.

        Parameters
        ----------
        held : (float, float) or None
            The lowest and highest command the servo may hold now (one value
            twice when it is known; two after a lost reply or request, when
            the servo holds either the new command or the one before); None
            before the first command.
        """
        low, high = self.low, self.high
        if held is not None and math.isfinite(self.max_step):
            # commands sent from such a window lie inside the band and within max_step of each other, so
            # the window holds them all and is never empty
            low = max(low, held[1] - self.max_step)
            high = min(high, held[0] + self.max_step)
            if low > high and (held[0] + self.max_step < self.low or held[1] - self.max_step > self.high):
                # the servo holds a place away from the band (the position read at enable): move toward the
                # band by max_step per sample, never past the range (the range wins over max_step)
                low = min(max(held[1] - self.max_step, self.minimum), self.maximum)
                high = max(min(held[0] + self.max_step, self.maximum), self.minimum)
            elif low > high:  # held commands that broke the rule (rounding): stay between them
                low = high = min(max(0.5 * (held[0] + held[1]), self.low), self.high)
        return low, high

    def clamp(self, requested: float, held: float | tuple[float, float] | None = None) -> float:
        """The command to send for ``requested`` (see :meth:`window`).

        Parameters
        ----------
        requested : float
            The command asked for.
        held : float or (float, float) or None
            The command the servo holds (or the lowest and highest it may hold);
            None before the first command.
        """
        if isinstance(held, (int, float)):
            held = (float(held), float(held))
        low, high = self.window(held)
        return min(max(requested, low), high)

    def position_ok(self, position: float) -> bool:
        """Whether a measured position lies within ``guard`` of the range (always, when the guard is off)."""
        if math.isinf(self.guard):
            return True
        return self.minimum - self.guard <= position <= self.maximum + self.guard


@dataclass(frozen=True, slots=True)
class Reading:
    """One measurement as a driver primitive returns it, in native units.

    Attributes
    ----------
    position : float
        Measured position, native unit.
    device_time : float or None
        The device's clock in seconds (may wrap; the base unwraps it).
    velocity, current : float or None
        Optional extra measurements, native units.
    """

    position: float
    device_time: float | None = None
    velocity: float | None = None
    current: float | None = None


@dataclass(frozen=True, slots=True)
class PendingCommand:
    """A command on its way (:meth:`Driver.begin_exchange`), user unit.

    Attributes
    ----------
    requested : float
        The command asked for.
    command : float
        The command to send (limited, rounded).
    clamped : bool
        Whether the limits changed it.
    slot : int or None
        The session's slot.
    """

    requested: float
    command: float
    clamped: bool
    slot: int | None


@dataclass(frozen=True, slots=True)
class Measurement:
    """One exchange as the user sees it: in the user's units.

    Attributes
    ----------
    requested : float
        The command asked for.
    command : float
        The command actually sent: after the safety limits, rounded to the
        device's resolution (:attr:`Driver.command_step`).
    clamped : bool
        Whether the limits changed the command.
    position : float
        Measured position.
    device_time : float or None
        Device clock in seconds, unwrapped, when the device has one.
    velocity, current : float or None
        Extra measurements, converted by the driver to user units where it
        knows how (see the driver's documentation), else native.
    """

    requested: float
    command: float
    clamped: bool
    position: float
    device_time: float | None = None
    velocity: float | None = None
    current: float | None = None


@dataclass
class DriverStats:
    """Counters a driver keeps while open.

    Attributes
    ----------
    exchanges : int
        Commands exchanged for a measurement.
    clamped : int
        Commands the safety limits changed before they were sent.
    errors : int
        Failed calls of a primitive (timeouts included).
    timeouts : int
        Calls that got no answer in time.
    rejected : int
        Replies thrown away as corrupted (bad CRC, length, framing): never used.
    stale : int
        Replies that came after their request had timed out (matched by
        sequence number), discarded.
    unconfirmed : int
        Commands the servo's read-back showed it did not get (a corrupted
        request it dropped); their samples are not used.
    """

    exchanges: int = 0
    clamped: int = 0
    errors: int = 0
    timeouts: int = 0
    rejected: int = 0
    stale: int = 0
    unconfirmed: int = 0


@dataclass(frozen=True)
class Option:
    """One URL option a driver accepts.

    Parameters
    ----------
    parse : callable
        Turns the option's text into a value; raises ValueError on bad text.
    help : str
        One line for ``--help`` and error messages, with the unit.
    keyword : str, optional
        Constructor keyword it maps to (default: the option's name).
    """

    parse: Callable[[str], Any]
    help: str
    keyword: str | None = None


@dataclass(frozen=True)
class DriverURL:
    """A parsed driver URL ``scheme://location/path?key=value&...``.

    Attributes
    ----------
    raw : str
        The URL as given.
    scheme : str
        ``sim``, ``serial``, ``can``, ``dxl``, ...
    host : str
        The part after ``//`` up to the path (the CAN interface, e.g. ``virtual``).
    path : str
        The path (a serial port, a CAN channel).
    options : mapping of str to str
        The query options, as text.
    """

    raw: str
    scheme: str
    host: str
    path: str
    options: Mapping[str, str] = field(default_factory=dict)


def _float(text: str) -> float:
    return float(text)


#: Options every driver accepts: the safety limits, in the user's unit.
COMMON_OPTIONS: dict[str, Option] = {
    "min": Option(_float, "lowest command allowed (user unit)", "minimum"),
    "max": Option(_float, "highest command allowed (user unit)", "maximum"),
    "max_step": Option(_float, "largest command change per sample (user unit)", "max_step"),
    "amplitude": Option(_float, "largest command distance from centre (user unit)", "amplitude"),
    "centre": Option(_float, "operating point the amplitude is measured from (user unit)", "centre"),
    "guard": Option(_float, "stop if the measured position leaves [min, max] by more than this (user unit)", "guard"),
}


#: Signals that would interrupt a torque-off half done; held while a driver closes.
_HELD_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextlib.contextmanager
def _stop_signals_held() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP inside the block and deliver them after it (main thread only).

    Python runs signal handlers in the main thread between two bytecodes, so
    a second Ctrl-C would raise inside the torque-off request; masking the
    signal in this thread alone would not help (the kernel hands it to
    another thread, a bus reader's). The handlers are swapped for one that
    notes the signal, and the first one noted is raised again afterwards,
    to whatever handler was there before.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:  # noqa: ARG001 - a signal handler's signature
        noted.append(signum)

    previous: dict[int, Any] = {}
    for sig in _HELD_SIGNALS:
        handler = signal.getsignal(sig)
        if handler is not None:  # None: installed outside Python, cannot be restored
            previous[sig] = signal.signal(sig, note)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if noted:
            signal.raise_signal(noted[0])


class Driver(abc.ABC):
    """Base of every servo driver (see the module docstring for the contract).

    Parameters
    ----------
    limits : Limits, optional
        Safety limits on the command (user unit); default none.
    position_unit : UnitConversion, optional
        Native position unit -> user unit.
    command_unit : UnitConversion, optional
        Native command unit -> user unit; default the position unit (position
        mode).
    """

    scheme: ClassVar[str] = ""
    options: ClassVar[Mapping[str, Option]] = {}
    clock_wrap_s: ClassVar[float | None] = None
    clock_resolution_s: ClassVar[float] = 0.0
    carries_slots: ClassVar[bool] = False
    watchdog_fed_by_exchanges: ClassVar[bool] = True

    def __init__(
        self,
        *,
        limits: Limits | None = None,
        position_unit: UnitConversion | None = None,
        command_unit: UnitConversion | None = None,
    ) -> None:
        self.limits = limits if limits is not None else Limits()
        self.position_unit = position_unit if position_unit is not None else UnitConversion()
        self.command_unit = command_unit if command_unit is not None else self.position_unit
        #: Smallest change of the command the device applies, native unit (None: continuous).
        self.command_step: float | None = None
        #: The device's own watchdog as configured, s (None: none, or off); see the module docstring.
        self.watchdog_s: float | None = None
        #: Which shaft the position readings are of: "output" or "motor" (:mod:`servoid.readings_side`).
        self.readings_side: str = readings_side.OUTPUT
        self.stats = DriverStats()
        self.url: str = ""
        self._is_open = False
        self._torque = False
        self._last_command: float | None = None
        self._held: tuple[float, float] | None = None
        self._clock_last: float | None = None
        self._clock_offset = 0.0
        self._identity_cache: dict[str, Any] | None = None
        self.sample_period_s: float | None = None

    # ---- primitives -----------------------------------------------------------------
    @abc.abstractmethod
    def _open(self) -> None:
        """Acquire the transport and check the servo answers."""

    @abc.abstractmethod
    def _close(self) -> None:
        """Release the transport."""

    @abc.abstractmethod
    def _set_torque(self, enabled: bool) -> None:
        """Switch the output stage on or off."""

    @abc.abstractmethod
    def _exchange(self, command: float, slot: int | None) -> Reading:
        """Send one command (native unit) for the session's slot ``slot``; return the measurement that answers it."""

    def _read(self) -> Reading:
        """A measurement without a command; drivers that can, override this."""
        raise DriverError(f"{type(self).__name__} cannot read without commanding")

    def _identity(self) -> dict[str, Any]:
        """What the servo says it is; drivers that know, override this."""
        return {}

    def _set_period(self, period_s: float) -> None:  # noqa: B027 - optional, the default ignores it
        """Learn the sample period; drivers whose device runs on its own time grid override this."""

    # ---- construction from a URL -------------------------------------------------------
    @classmethod
    def accepted_options(cls) -> dict[str, Option]:
        """All URL options this driver accepts: its own and the common limits."""
        return {**COMMON_OPTIONS, **cls.options}

    @classmethod
    def parse_options(cls, url: DriverURL) -> dict[str, Any]:
        """URL options as constructor keywords; unknown options are rejected by name."""
        accepted = cls.accepted_options()
        unknown = sorted(set(url.options) - set(accepted))
        if unknown:
            valid = ", ".join(f"{k} ({o.help})" for k, o in sorted(accepted.items()))
            raise ConfigError(f"{url.raw}: unknown option(s) {', '.join(unknown)}; {cls.scheme}:// accepts {valid}")
        kwargs: dict[str, Any] = {}
        limit_kwargs: dict[str, float] = {}
        for name, text in url.options.items():
            opt = accepted[name]
            try:
                value = opt.parse(text)
            except (TypeError, ValueError) as exc:
                raise ConfigError(f"{url.raw}: option {name}={text!r} is invalid: {opt.help} ({exc})") from None
            key = opt.keyword or name
            if name in COMMON_OPTIONS:
                limit_kwargs[key] = value
            else:
                kwargs[key] = value
        if limit_kwargs:
            kwargs["limits"] = Limits(**limit_kwargs)
        return kwargs

    @classmethod
    def from_url(cls, url: DriverURL) -> Driver:
        """Build a driver (not yet open) from a parsed URL.

        The default passes the parsed options as keywords; drivers whose URL
        location (port, bus, channel) matters override this and call
        :meth:`parse_options`.
        """
        driver = cls(**cls.parse_options(url))
        driver.url = url.raw
        return driver

    # ---- life cycle ----------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return self._is_open

    @property
    def torque_enabled(self) -> bool:
        return self._torque

    def open(self) -> Driver:
        """Open the transport (torque stays off until :meth:`enable`); returns self."""
        if self._is_open:
            return self
        self._call(self._open)
        self._is_open = True
        self._last_command = None
        self._held = None
        self._clock_last = None
        self._clock_offset = 0.0
        return self

    def enable(self) -> None:
        """Switch the torque on.

        With a finite ``max_step`` and a driver that can read without
        commanding, the position read here counts as the command the servo
        holds: the first command then lies within ``max_step`` of where the
        servo is, not only of the band (a servo resting away from the band is
        brought to it in steps of ``max_step``).
        """
        self._require_open()
        self._call(self._set_torque, True)
        self._torque = True
        if self._held is None and math.isfinite(self.limits.max_step) and type(self)._read is not Driver._read:
            self._hold_where_it_rests()

    def _hold_where_it_rests(self) -> None:
        """Take the position read now as the command the servo holds (see :meth:`enable`).

        A read that fails leaves the band as the only bound of the first
        command (as for a driver that cannot read), with a warning; a servo
        outside the range is switched off by the guard.
        """
        try:
            reading = self._call(self._read)
        except DriverError as exc:
            log.warning("%s: could not read the position at enable (%s): the first command is bounded by the "
                        "band only", self.describe(), exc)  # fmt: skip
            return
        position = self.position_unit.to_user(reading.position)  # not a sample: the clock is left alone
        self._guard(position)
        if math.isfinite(position):
            self._held = (position, position)

    def set_sample_period(self, period_s: float) -> None:
        """Tell the driver (and through it the device) the period of the exchanges to come, in seconds."""
        self._require_open()
        period = validation.positive("period_s", period_s)
        if self.watchdog_fed_by_exchanges and self.watchdog_s is not None and 2.0 * period > self.watchdog_s:
            raise ConfigError(
                f"period_s (={period!r}) must be below half the device's watchdog ({self.watchdog_s:g} s): it would "
                "switch the servo off between two samples; sample faster or raise watchdog= in the URL"
            )
        self._call(self._set_period, period)
        self.sample_period_s = period

    @property
    def last_command(self) -> float | None:
        """The last command sent (user unit), answered or not; None before the first.

        When a reply is lost the servo most likely applied the command (a lost
        request is rarer): this is what a recording says the servo held.
        """
        return self._last_command

    @property
    def possibly_held(self) -> tuple[float, float] | None:
        """The lowest and highest command the servo may hold now (user unit); None before the first.

        One value twice after an answered exchange; after a lost reply (or
        request) the servo holds either that command or an earlier one, and
        the next command is kept within ``max_step`` of every one of them.
        """
        return self._held

    def disable(self) -> None:
        """Switch the torque off."""
        self._require_open()
        self._call(self._set_torque, False)
        self._torque = False

    def close(self) -> None:
        """Switch the torque off and release the transport; safe to call twice.

        A servo that does not answer the torque-off request is still closed;
        the failure is logged and counted, never raised from here, so that
        closing in an error path does not hide the original error.
        """
        if not self._is_open:
            return
        with _stop_signals_held():
            try:
                self._set_torque(False)
                self._torque = False
            except Exception as exc:  # noqa: BLE001 - must not mask the error being handled
                self.stats.errors += 1
                log.warning("%s: could not switch the torque off while closing: %s", self.describe(), exc)
            finally:
                self._is_open = False
                try:
                    self._close()
                except Exception as exc:  # noqa: BLE001
                    log.warning("%s: error while closing: %s", self.describe(), exc)

    def __enter__(self) -> Driver:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # last resort: never leave a servo powered by accident
        try:
            if getattr(self, "_is_open", False):
                self.close()
        except Exception:  # noqa: BLE001
            pass

    # ---- per sample ----------------------------------------------------------------------
    def exchange(self, u: float, *, slot: int | None = None) -> Measurement:
        """Command ``u`` (user unit), clamped to the limits, and return the measurement.

        Parameters
        ----------
        u : float
            The command asked for, user unit.
        slot : int, optional
            The sampling session's slot number of this sample (only
            increasing); passed on to the driver's ``_exchange``.

        Raises
        ------
        ConfigError
            If ``u`` is not finite, or ``slot`` is not an integer >= 0.
        DriverTimeout
            If the servo did not answer in time.
        DriverError
            For any other failure of the transport or the servo.
        """
        pending = self.begin_exchange(u, slot=slot)
        reading = self._call(self._exchange, self.command_unit.to_native(pending.command), pending.slot)
        return self.end_exchange(pending, reading)

    def begin_exchange(self, u: float, *, slot: int | None = None) -> PendingCommand:
        """The first half of :meth:`exchange`: check ``u``, apply the limits and the rounding, note the command as sent.

        For a group transaction over several servos of one bus
        (:mod:`servoid.drivers.bus`), which sends every joint's command in one
        packet: each joint's driver begins, the group exchanges, each joint's
        driver ends (:meth:`end_exchange`). :meth:`exchange` is both halves
        around the driver's own ``_exchange``.

        Parameters
        ----------
        u : float
            The command asked for, user unit.
        slot : int, optional
            The session's slot number.
        """
        self._require_open()
        requested = float(u)
        if not math.isfinite(requested):
            raise ConfigError(f"command u (={requested!r}) must be finite")
        if slot is not None:
            slot = validation.integer("slot", slot, minimum=0)
        low, high = self.limits.window(self._held)
        limited = min(max(requested, low), high)
        clamped = limited != requested
        if clamped:
            self.stats.clamped += 1
        command = self._round(limited, low, high)
        # From here the servo may hold this command, whether its reply comes back or not (a lost
        # reply), or still the one before (a lost request): the next command must respect both.
        self._last_command = command
        held = self._held
        self._held = (command, command) if held is None else (min(held[0], command), max(held[1], command))
        return PendingCommand(requested, command, clamped, slot)

    def end_exchange(self, pending: PendingCommand, reading: Reading) -> Measurement:
        """The second half of :meth:`exchange`: the servo answered ``reading`` to ``pending``'s command.

        Parameters
        ----------
        pending : PendingCommand
            What :meth:`begin_exchange` returned.
        reading : Reading
            The servo's answer, native units.
        """
        self._held = (pending.command, pending.command)
        self.stats.exchanges += 1
        measurement = self._measurement(reading, pending.requested, pending.command, pending.clamped)
        self._guard(measurement.position)
        return measurement

    def call(self, func: Callable[..., Any], *args: Any) -> Any:
        """``func(*args)`` with this driver's error wrapping and counters (for a group transaction of a bus).

        Parameters
        ----------
        func : callable
            A primitive.
        *args
            Its arguments.
        """
        return self._call(func, *args)

    def quantise(self, command: float) -> float:
        """``command`` (user unit, within the limits) as the device applies it: the nearest step inside the limits.

        Rounding never carries a command past a limit, not even by half a
        step; a range narrower than one step gets the nearest step.
        """
        return self._round(command, self.limits.low, self.limits.high)

    def _round(self, command: float, low: float, high: float) -> float:
        """``command`` on the device's grid, the nearest step inside ``[low, high]`` (the limits' window)."""
        step = self.command_step
        if step is None:
            return command
        steps = self.command_unit.to_native(command) / step
        for candidate in (round(steps), math.floor(steps), math.ceil(steps)):
            user = self.command_unit.to_user(candidate * step)
            if low <= user <= high:
                return user
        # a window narrower than one step: it holds the commands the servo may hold, which lie on the grid
        held = self._held
        if held is not None:
            return held[0] if abs(held[0] - command) <= abs(held[1] - command) else held[1]
        return self.command_unit.to_user(round(steps) * step)

    def read(self) -> Measurement:
        """A measurement without commanding (only for drivers that support it)."""
        self._require_open()
        reading = self._call(self._read)
        last = self._last_command if self._last_command is not None else math.nan
        measurement = self._measurement(reading, last, last, False)
        self._guard(measurement.position)
        return measurement

    @property
    def identity(self) -> dict[str, Any]:
        """What the servo says it is (only the readings' side when the driver cannot tell); cached.

        Always holds ``readings``: which shaft the positions are of (:attr:`readings_side`).
        """
        if self._identity_cache is None:
            self._identity_cache = dict(self._call(self._identity)) if self._is_open else {}
        side = readings_side.check("readings_side", self.readings_side)
        return {**self._identity_cache, readings_side.METADATA_KEY: side}

    def describe(self) -> str:
        """A short name for messages: the URL, or the class name."""
        return self.url or type(self).__name__

    # ---- helpers -------------------------------------------------------------------------
    def _require_open(self) -> None:
        if not self._is_open:
            raise DriverError(f"{self.describe()} is not open")

    def _guard(self, position: float) -> None:
        if self.limits.position_ok(position):
            return
        lim = self.limits
        try:
            self.disable()
        except ServoidError as exc:
            log.warning("%s: could not switch the torque off after a position out of range: %s", self.describe(), exc)
        raise PositionOutOfRange(
            f"{self.describe()}: measured position {position!r} {self.position_unit.unit} lies outside "
            f"[{lim.minimum!r}, {lim.maximum!r}] by more than guard={lim.guard!r}; torque switched off"
        )

    def _call(self, func: Callable[..., Any], *args: Any) -> Any:
        try:
            return func(*args)
        except DriverTimeout:
            self.stats.errors += 1
            self.stats.timeouts += 1
            raise
        except ServoidError:
            self.stats.errors += 1
            raise
        except TimeoutError as exc:
            self.stats.errors += 1
            self.stats.timeouts += 1
            raise DriverTimeout(f"{self.describe()}: no answer in time ({exc})") from exc
        except Exception as exc:  # noqa: BLE001 - vendor libraries raise anything
            self.stats.errors += 1
            raise DriverError(f"{self.describe()}: {type(exc).__name__}: {exc}") from exc

    def _measurement(self, reading: Reading, requested: float, command: float, clamped: bool) -> Measurement:
        return Measurement(
            requested=requested,
            command=command,
            clamped=clamped,
            position=self.position_unit.to_user(reading.position),
            device_time=self._unwrap(reading.device_time),
            velocity=reading.velocity,
            current=reading.current,
        )

    def _unwrap(self, t: float | None) -> float | None:
        if t is None:
            return None
        wrap = self.clock_wrap_s
        if wrap is not None and self._clock_last is not None and t < self._clock_last - wrap / 2:
            self._clock_offset += wrap
        self._clock_last = t
        return t + self._clock_offset
