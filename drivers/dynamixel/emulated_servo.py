"""One emulated X-series servo: its control table, its rules, and the servo behind it (a twin, or the bench plant).

:class:`EmulatedServo` knows nothing about bytes on a wire; the emulator
(:mod:`servoid.drivers.dynamixel.emulator`) decodes packets and calls
:meth:`~EmulatedServo.read`, :meth:`~EmulatedServo.write` and friends, which
return the error number the servo puts in its status packet.

What the emulated servo does
----------------------------
* The control table of :mod:`~servoid.drivers.dynamixel.control_table`, with
  its initial values; read-only entries, partial writes of an entry, values out
  of range and the EEPROM lock while the torque is on are refused with the
  e-manual's error numbers (Access, Data Length, Data Range, Data Limit).
* **The servo** (:mod:`servoid.drivers.servos`): the ``xm430`` twin unless
  another is given -- a Dynamixel XM430-W350 with its motor, gear, play,
  horn encoder and its own position PID at its own rate -- or the
  pseudo-Wiener bench plant (``servo="model"``). Present Position is the
  twin's horn encoder (``counts + 2048``), Present Velocity its filtered
  velocity estimate (0.229 rpm a unit), Present Current the winding current
  (2.69 mA a unit), Present PWM its duty (885 = 100 %), each as of the latest
  sample. Torque Enable switches the twin's drive stage: with the torque
  off it coasts. A twin that turns its stage off by itself (the ODrive
  twin's overspeed) sets the Overload Error bit of Hardware Error Status. A twin runs in the position modes (3, 4, 5) only; the
  current and PWM modes of its own current loop and output stage are not
  modelled, and Operating Mode refuses them (Data Range Error).
* **The plant, sampled**: the servo is a :class:`~servoid.drivers.sampled.SampledPlant`;
  each write of the goal of the active operating mode with the torque on is
  one sample of it. Protocol 2.0 carries no sample number, and a real servo's
  loop runs on its own clock; how many samples lie between two goals is
  therefore the servo's business:

  - ``period_s`` given: the servo runs on its own clock at that period -- a
    goal that comes ``n`` periods after the previous one (rounded) first runs
    ``n - 1`` samples on the held goal, as a position loop holds its set point
    while the host is silent. Sample at the servo's period, or the plant seen
    is another. (A READ reports the latest sample: the held samples are
    counted when the next goal comes, so that a READ the host sends late
    does not commit a sample the next goal belongs to);
  - no period: each goal is one sample, whatever the time between goals (the
    goals are the clock: any rate sees the same plant, but a slot the host
    skips is not seen);
  - ``slot_source`` (in-process tests only): a callable that returns the
    host's slot number of the goal being handled (the slot each
    command was sent with), told out of band because the protocol has no
    room for it; the servo then follows the host's slots exactly.

  Present Position, Velocity, Current and PWM change only when the plant does.
* Operating modes with the pseudo-Wiener plant (its input is in rad):

  - position (3, and 4, 5): the goal position, ``(goal - 2048) * 2 pi / 4096`` rad;
  - current (0): the goal current times :data:`CURRENT_GAIN` rad/A, as if the
    joint were held by a spring whose deflection is proportional to the
    current (so an identification in current mode finds a DC gain of 1 rad/A);
  - PWM (16): the goal PWM in percent times :data:`PWM_GAIN` rad/%;
  - velocity (1) is accepted but does not move the plant.

  Present Current in position and PWM mode is the current that would hold the
  same deflection, ``(u - y) / CURRENT_GAIN`` (an indication, not physics).
* Realtime Tick: milliseconds since boot from the injected ``clock``, wrapping
  at 32768. Present Velocity: the position change over the clock time between
  the last two samples.
* Hardware errors (:meth:`inject_hardware_error`): Hardware Error Status is
  set, the alert bit goes into every status packet, the torque is switched off
  when the error is one of Shutdown's bits, and the torque cannot be switched
  on again until a reboot.
* REBOOT restores the RAM area and clears hardware errors; the plant keeps its
  physical state (the gear does not move because the electronics restarted).
* Bus Watchdog (98), as the e-manual gives it: with the torque on and a value
  of 1..127 (x 20 ms), no instruction packet for that long stops the servo --
  it holds where it is (the goal becomes the present position; 0 current or
  PWM in those modes), Bus Watchdog reads -1 and the goals are read-only
  (a write gets a Data Range Error) until 0 is written to it. The emulator
  feeds it with every intact instruction packet that reaches the servo
  (:meth:`EmulatedServo.heard`) and checks it while the line is quiet
  (:meth:`EmulatedServo.check_watchdog`). ``on_event`` hears the watchdog
  expiring and the torque going off.
"""

from __future__ import annotations

from collections.abc import Callable

from servoid.drivers._pty_bus import return_delay_units, servo_plant
from servoid.drivers.clock import NS_PER_S, Clock, MonotonicClock
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel._emulator_facts import CURRENT_GAIN, PWM_GAIN
from servoid.drivers.dynamixel.control_table import Field, HardwareError, OperatingMode
from servoid.drivers.dynamixel.protocol import ErrorNumber
from servoid.drivers.sampled import PlantSample, SampledPlant
from servoid.drivers.servos import Servo

__all__ = ["EmulatedServo", "CURRENT_GAIN", "PWM_GAIN"]


_POSITION_MODES = (OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.CURRENT_BASED_POSITION)
#: Operating mode -> the goal entry whose write advances the plant.
_GOAL_OF_MODE: dict[int, Field] = {
    **{mode: ct.GOAL_POSITION for mode in _POSITION_MODES},
    OperatingMode.CURRENT: ct.GOAL_CURRENT,
    OperatingMode.PWM: ct.GOAL_PWM,
}
#: Entries whose value must lie in a fixed set or range (else Data Range Error).
_VALID_VALUES: dict[Field, range | frozenset[int]] = {
    ct.ID: range(0, 253),
    ct.BAUD_RATE: frozenset(ct.BAUD_RATES),
    ct.RETURN_DELAY_TIME: range(0, 255),
    ct.OPERATING_MODE: frozenset(int(m) for m in OperatingMode),
    ct.STATUS_RETURN_LEVEL: range(0, 3),
    ct.TORQUE_ENABLE: range(0, 2),
    ct.LED: range(0, 2),
    ct.BUS_WATCHDOG: range(0, 128),  # -1 is the servo's own: a host cannot write it
}
_GOALS = (ct.GOAL_PWM, ct.GOAL_CURRENT, ct.GOAL_VELOCITY, ct.GOAL_POSITION)


class EmulatedServo:
    """An X-series servo in memory (see the module docstring for what it emulates).

    Parameters
    ----------
    servo_id : int
        Initial ID (0..252).
    servo : Servo or str
        The mechanics behind the servo (default the ``xm430`` twin; text as
        :func:`~servoid.drivers.servos.parse_servo` reads it: ``"model"``,
        ``"xm430?play_deg=0.8"``).
    model_number, firmware : int
        What Model Number (0) and Firmware Version (6) report.
    return_delay_us : int
        Initial Return Delay Time in microseconds (even, 0..508; the factory
        setting is 500).
    clock : Clock, optional
        Drives the Realtime Tick, the plant's own sample clock and Present
        Velocity (default the real one); inject a
        :class:`~servoid.drivers.clock.VirtualClock` for deterministic tests.
    period_s : float, optional
        The servo's own sample period (see the module docstring); None: one
        sample per goal (a twin then runs one period at
        :data:`~servoid.drivers.servos.DEFAULT_RATE_HZ` per goal).

    Attributes
    ----------
    slot_source : callable or None
        In-process tests: returns the host's slot of the goal being written.
    on_event : callable or None
        Called with one line when the Bus Watchdog expires or the torque goes off.
    """

    def __init__(
        self,
        servo_id: int = 1,
        *,
        servo: Servo | str = "xm430",
        model_number: int = ct.MODEL_NUMBER.initial,
        firmware: int = ct.FIRMWARE_VERSION.initial,
        return_delay_us: int = 500,
        clock: Clock | None = None,
        period_s: float | None = None,
    ) -> None:
        delay = 2 * return_delay_units(servo_id, return_delay_us, max_id=252)
        self._clock: Clock = clock if clock is not None else MonotonicClock()
        self.servo, self._sampled = servo_plant(servo, period_s)
        self.slot_source: Callable[[], int | None] | None = None
        self._memory = bytearray(ct.TABLE_SIZE)
        self._registered: tuple[int, bytes] | None = None
        for f in ct.FIELDS:
            self._put(f, f.initial)
        self._put(ct.MODEL_NUMBER, model_number)
        self._put(ct.FIRMWARE_VERSION, firmware)
        self._put(ct.ID, servo_id)
        self._put(ct.RETURN_DELAY_TIME, delay // 2)
        self._eeprom_defaults = bytes(self._memory[: ct.TORQUE_ENABLE.address])
        self._boot = self._clock.now_ns()
        #: Number of reboots.
        self.reboots = 0
        self.on_event: Callable[[str], None] | None = None
        self._heard_ns = self._boot  # when the last intact instruction packet reached the servo
        self._powered = False  # Torque Enable as the plant last followed it

    # ---- state -----------------------------------------------------------------------
    def value(self, field: Field) -> int:
        """The current value of an entry (signed where the entry is)."""
        if field is ct.REALTIME_TICK:
            self._update_tick()
        return ct.decode_value(field, self._memory, field.address)

    @property
    def id(self) -> int:
        return self.value(ct.ID)

    @property
    def torque(self) -> bool:
        return bool(self.value(ct.TORQUE_ENABLE))

    @property
    def alert(self) -> bool:
        """Whether a hardware error is pending (the alert bit of status packets)."""
        return self.value(ct.HARDWARE_ERROR_STATUS) != 0

    @property
    def status_return_level(self) -> int:
        return self.value(ct.STATUS_RETURN_LEVEL)

    @property
    def return_delay_s(self) -> float:
        return self.value(ct.RETURN_DELAY_TIME) * ct.SECONDS_PER_RETURN_DELAY_UNIT

    @property
    def plant(self) -> SampledPlant:
        """The mechanics and their sample count (the model can be swapped while running, to emulate wear)."""
        return self._sampled

    @property
    def steps(self) -> int:
        """Samples the plant has advanced (goal writes with the torque on, and held samples)."""
        return self._sampled.index + 1

    def _put(self, field: Field, value: int) -> None:
        self._memory[field.address : field.end] = ct.encode_value(field, value)

    def _update_tick(self) -> None:
        ms = (self._clock.now_ns() - self._boot) // 1_000_000
        self._put(ct.REALTIME_TICK, ms % int(ct.TICK_WRAP_S * 1000))

    # ---- instructions ------------------------------------------------------------------
    def read(self, address: int, length: int) -> tuple[ErrorNumber, bytes]:
        """READ: the bytes ``address .. address + length - 1`` (Access Error beyond the table)."""
        if length < 1 or address < 0 or address + length > ct.TABLE_SIZE:
            return ErrorNumber.ACCESS, b""
        if address < ct.REALTIME_TICK.end and address + length > ct.REALTIME_TICK.address:
            self._update_tick()
        return ErrorNumber.NONE, bytes(self._memory[address : address + length])

    def write(self, address: int, data: bytes) -> ErrorNumber:
        """WRITE: check the whole write first, then apply it (nothing is written on error)."""
        error = self.check_write(address, data)
        if error:
            return error
        torque_before = self.torque
        self._memory[address : address + len(data)] = data
        self._follow_torque()
        goal = _GOAL_OF_MODE.get(self.value(ct.OPERATING_MODE))
        if goal is not None and torque_before and self.torque and address <= goal.address < address + len(data):
            self._step()
        return ErrorNumber.NONE

    def check_write(self, address: int, data: bytes) -> ErrorNumber:
        """The error number a WRITE of ``data`` at ``address`` would get (0 if accepted)."""
        end = address + len(data)
        if not data or address < 0 or end > ct.TABLE_SIZE:
            return ErrorNumber.ACCESS
        fields = ct.fields_in(address, len(data))
        if any(f.address < address or f.end > end for f in fields):
            return ErrorNumber.DATA_LENGTH  # only part of an entry
        if sum(f.size for f in fields) != len(data):
            return ErrorNumber.ACCESS  # the write covers reserved addresses
        torque = self.torque
        for f in fields:
            if not f.writable or (f.eeprom and torque):
                return ErrorNumber.ACCESS
        for f in fields:
            error = self._check_value(f, ct.decode_value(f, data, f.address - address))
            if error:
                return error
        return ErrorNumber.NONE

    def _check_value(self, field: Field, value: int) -> ErrorNumber:
        if field in _GOALS and self.value(ct.BUS_WATCHDOG) == ct.BUS_WATCHDOG_EXPIRED:
            return ErrorNumber.DATA_RANGE  # goals are read-only after the Bus Watchdog expired
        valid = _VALID_VALUES.get(field)
        if valid is not None and value not in valid:
            return ErrorNumber.DATA_RANGE
        if field is ct.TORQUE_ENABLE and value == 1 and self.alert:
            return ErrorNumber.RESULT_FAIL  # a servo with a hardware error refuses the torque until rebooted
        if field is ct.OPERATING_MODE and self.servo.twin is not None and value not in _POSITION_MODES:
            return ErrorNumber.DATA_RANGE  # the twin's current loop and PWM output mode are not modelled
        mode = self.value(ct.OPERATING_MODE)
        if field is ct.GOAL_POSITION and mode == OperatingMode.POSITION:
            if not self.value(ct.MIN_POSITION_LIMIT) <= value <= self.value(ct.MAX_POSITION_LIMIT):
                return ErrorNumber.DATA_LIMIT
        if field is ct.GOAL_CURRENT and abs(value) > self.value(ct.CURRENT_LIMIT):
            return ErrorNumber.DATA_LIMIT
        if field is ct.GOAL_PWM and abs(value) > self.value(ct.PWM_LIMIT):
            return ErrorNumber.DATA_LIMIT
        return ErrorNumber.NONE

    def reg_write(self, address: int, data: bytes) -> ErrorNumber:
        """REG_WRITE: check now, apply on ACTION; sets Registered Instruction."""
        error = self.check_write(address, data)
        if error:
            return error
        self._registered = (address, bytes(data))
        self._put(ct.REGISTERED_INSTRUCTION, 1)
        return ErrorNumber.NONE

    def action(self) -> ErrorNumber:
        """ACTION: apply the registered write (Instruction Error when there is none)."""
        if self._registered is None:
            return ErrorNumber.INSTRUCTION
        address, data = self._registered
        self._registered = None
        self._put(ct.REGISTERED_INSTRUCTION, 0)
        return self.write(address, data)

    def reboot(self) -> None:
        """REBOOT: RAM area back to its initial values, hardware errors cleared, tick restarted."""
        for f in ct.FIELDS:
            if not f.eeprom:
                self._put(f, f.initial)
        self._registered = None
        self._follow_torque()
        self._show_plant_output(self._sampled.plant.y, velocity=0.0)
        self._show_twin()
        self._put(ct.GOAL_POSITION, self.value(ct.PRESENT_POSITION))
        self._boot = self._clock.now_ns()
        self.reboots += 1

    def factory_reset(self, option: int) -> ErrorNumber:
        """FACTORY_RESET: EEPROM to factory values (0xFF all, 0x01 all but ID, 0x02 all but ID and baud)."""
        if option not in (0x01, 0x02, 0xFF):
            return ErrorNumber.DATA_RANGE
        if self.torque:
            return ErrorNumber.ACCESS
        keep = {0x01: (ct.ID,), 0x02: (ct.ID, ct.BAUD_RATE), 0xFF: ()}[option]
        kept = [(f, self.value(f)) for f in keep]
        self._memory[: len(self._eeprom_defaults)] = self._eeprom_defaults
        self._put(ct.ID, 1)
        self._put(ct.BAUD_RATE, ct.BAUD_RATE.initial)
        self._put(ct.RETURN_DELAY_TIME, ct.RETURN_DELAY_TIME.initial)
        for f, v in kept:
            self._put(f, v)
        return ErrorNumber.NONE

    # ---- faults --------------------------------------------------------------------------
    def inject_hardware_error(self, bits: HardwareError) -> None:
        """Raise a hardware error as the servo's own protection would.

        Sets Hardware Error Status; if any bit is one of Shutdown's, the torque
        goes off (as on the real servo).
        """
        status = self.value(ct.HARDWARE_ERROR_STATUS) | int(bits)
        self._put(ct.HARDWARE_ERROR_STATUS, status)
        if status & self.value(ct.SHUTDOWN):
            self._put(ct.TORQUE_ENABLE, 0)
            self._follow_torque()

    # ---- the plant -------------------------------------------------------------------------
    def plant_input(self) -> float | None:
        """The plant input (rad) the goal of the active mode stands for; None in velocity mode."""
        mode = self.value(ct.OPERATING_MODE)
        if mode in _POSITION_MODES:
            return (self.value(ct.GOAL_POSITION) - ct.POSITION_CENTRE) * ct.RAD_PER_COUNT
        if mode == OperatingMode.CURRENT:
            return self.value(ct.GOAL_CURRENT) * ct.AMPERE_PER_UNIT * CURRENT_GAIN
        if mode == OperatingMode.PWM:
            return self.value(ct.GOAL_PWM) * ct.PERCENT_PER_PWM_UNIT * PWM_GAIN
        return None

    def _follow_torque(self) -> None:
        """The plant follows goals while Torque Enable is 1 (a new count of samples each time it comes on)."""
        was, self._powered = self._powered, self.torque
        if self.torque:
            if not was:
                self._heard_ns = self._clock.now_ns()  # the watchdog measures from the torque coming on
            self._sampled.enable()
        else:
            self._sampled.disable()
            if was:
                self._event("torque off")

    # ---- the Bus Watchdog -------------------------------------------------------------------
    def heard(self, at_ns: int) -> None:
        """An intact instruction packet reached the servo at ``at_ns``: it feeds the Bus Watchdog."""
        self._heard_ns = max(self._heard_ns, at_ns)

    def watchdog_deadline_ns(self) -> int | None:
        """When the Bus Watchdog expires if nothing is heard before (None: it is not running)."""
        units = self.value(ct.BUS_WATCHDOG)
        if units <= 0 or not self.torque:
            return None
        return self._heard_ns + round(units * ct.SECONDS_PER_BUS_WATCHDOG_UNIT * NS_PER_S)

    def check_watchdog(self, now_ns: int) -> bool:
        """Stop the servo if its Bus Watchdog has expired by ``now_ns``; whether it did now."""
        deadline = self.watchdog_deadline_ns()
        if deadline is None or now_ns < deadline:
            return False
        silent_ms = (now_ns - self._heard_ns) / 1e6
        self._put(ct.BUS_WATCHDOG, ct.BUS_WATCHDOG_EXPIRED)
        mode = self.value(ct.OPERATING_MODE)
        if mode in _POSITION_MODES:
            self._put(ct.GOAL_POSITION, self.value(ct.PRESENT_POSITION))  # it stops where it is
        self._put(ct.GOAL_CURRENT, 0 if mode == OperatingMode.CURRENT else self.value(ct.GOAL_CURRENT))
        self._put(ct.GOAL_PWM, 0 if mode == OperatingMode.PWM else self.value(ct.GOAL_PWM))
        self._event(f"bus watchdog expired after {silent_ms:.0f} ms without an instruction: stopped, goals locked")
        return True

    def _event(self, what: str) -> None:
        if self.on_event is not None:
            self.on_event(f"servo {self.id}: {what}")

    def _step(self) -> None:
        u = self.plant_input()
        if u is None:
            return
        slot = self.slot_source() if self.slot_source is not None else None
        self._show(self._sampled.command(u, self._clock.now_ns(), slot=slot), u)

    def _show(self, sample: PlantSample, u: float) -> None:
        self._show_plant_output(sample.position, velocity=self._sampled.velocity, u=u)
        self._show_twin()

    def _show_twin(self) -> None:
        """A twin's registers in the control table's units (velocity, current and PWM are its own, not deflections)."""
        twin = self._sampled.twin
        if twin is None:
            return
        if twin.twin.read().fault is not None and not self.alert:
            # the twin turned its output stage off by itself (an ODrive twin's overspeed): the X series says
            # so with a hardware error, as its own protections do, rather than answer for a coasting servo
            self._event(f"the twin turned its output stage off ({twin.twin.read().fault}): Overload Error")
            self.inject_hardware_error(HardwareError.OVERLOAD)
        r = twin.reading
        self._put(
            ct.PRESENT_VELOCITY, _clip(ct.PRESENT_VELOCITY, round(r.velocity_rad_s / ct.RAD_PER_S_PER_VELOCITY_UNIT))
        )
        self._put(ct.MOVING, int(abs(self.value(ct.PRESENT_VELOCITY)) > self.value(ct.MOVING_THRESHOLD)))
        self._put(ct.PRESENT_CURRENT, _clip(ct.PRESENT_CURRENT, round(r.current_a / ct.AMPERE_PER_UNIT)))
        self._put(ct.PRESENT_PWM, _clip(ct.PRESENT_PWM, round(r.duty * 100.0 / ct.PERCENT_PER_PWM_UNIT)))

    def _show_plant_output(self, y: float, *, velocity: float, u: float | None = None) -> None:
        self._put(ct.PRESENT_POSITION, _clip(ct.PRESENT_POSITION, round(y / ct.RAD_PER_COUNT) + ct.POSITION_CENTRE))
        self._put(ct.PRESENT_VELOCITY, _clip(ct.PRESENT_VELOCITY, round(velocity / ct.RAD_PER_S_PER_VELOCITY_UNIT)))
        moving = abs(self.value(ct.PRESENT_VELOCITY)) > self.value(ct.MOVING_THRESHOLD)
        self._put(ct.MOVING, int(moving))
        mode = self.value(ct.OPERATING_MODE)
        deflection = 0.0 if u is None else u - y
        if mode == OperatingMode.CURRENT:
            current = self.value(ct.GOAL_CURRENT)
        else:
            current = round(deflection / CURRENT_GAIN / ct.AMPERE_PER_UNIT)
        if mode == OperatingMode.PWM:
            pwm = self.value(ct.GOAL_PWM)
        else:
            pwm = round(deflection / PWM_GAIN / ct.PERCENT_PER_PWM_UNIT)
        current_limit, pwm_limit = self.value(ct.CURRENT_LIMIT), self.value(ct.PWM_LIMIT)
        self._put(ct.PRESENT_CURRENT, max(-current_limit, min(current_limit, current)))
        self._put(ct.PRESENT_PWM, max(-pwm_limit, min(pwm_limit, pwm)))


def _clip(field: Field, value: int) -> int:
    return max(field.minimum, min(field.maximum, value))
