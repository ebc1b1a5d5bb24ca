"""One emulated Feetech STS servo: its memory table, its rules, and the twin behind it.

:class:`EmulatedServo` knows nothing about bytes on a wire; the emulator
(:mod:`servoid.drivers.feetech.emulator`) decodes packets and calls
:meth:`~EmulatedServo.read`, :meth:`~EmulatedServo.write` and friends.

What the emulated servo does
----------------------------
* The memory table of :mod:`~servoid.drivers.feetech.control_table` with an
  STS3215's factory values. A READ may span reserved bytes (they read 0); a
  WRITE to a read-only entry or a reserved byte changes nothing (an STS has no
  error number for it: its status error byte carries only its protections).
* The EEPROM area: a write changes the value at once; it is saved, and
  survives a restart, only while Lock (55) is 0 (the memory table's rule).
  :meth:`restart` (a brown-out: the supply dipped) brings the saved EEPROM
  and the SRAM's power-on values back -- the torque off.
* **The servo** (:mod:`servoid.drivers.servos`): the ``sts3215`` twin unless
  another is given (``servo="model"``: the pseudo-Wiener bench plant).
  Present Position is the twin's magnetic encoder (``counts + 2048``, 4096 a
  turn, sign-magnitude bit 15), Present Speed its velocity estimate (counts/s,
  bit 15), Present Load its duty (0.1 %, bit 10), Present Current its winding
  current (6.5 mA a unit). Goal Position is clipped to the position limits,
  as the servo's firmware does.
* **Sampled like every emulated servo** (:class:`~servoid.drivers.sampled.SampledPlant`):
  each write of Goal Position with the torque on is one sample; with
  ``period_s`` the servo runs on its own clock and holds its goal through the
  periods the host is silent; ``slot_source`` (in-process tests) tells it the
  host's slot of each goal.
* Protections (:meth:`inject_fault`): Status (65) shows the fault bits, every
  status packet carries them in its error byte, and the torque goes off when
  a bit is one of Unloading Condition's (19).
* No watchdog: the STS memory table has no communication timeout; a servo
  whose host died keeps its last goal, torque on.
"""

from __future__ import annotations

from collections.abc import Callable

from servoid.drivers._pty_bus import return_delay_units, servo_plant
from servoid.drivers.clock import Clock, MonotonicClock
from servoid.drivers.feetech import control_table as ct
from servoid.drivers.feetech.control_table import Field
from servoid.drivers.feetech.protocol import ErrorBit
from servoid.drivers.sampled import SampledPlant
from servoid.drivers.servos import Servo

__all__ = ["EmulatedServo"]


class EmulatedServo:
    """An STS servo in memory (see the module docstring for what it emulates).

    Parameters
    ----------
    servo_id : int
        Initial ID (0..253).
    servo : Servo or str
        The mechanics behind the servo (default the ``sts3215`` twin; text as
        :func:`~servoid.drivers.servos.parse_servo` reads it).
    return_delay_us : int
        Initial Return Delay Time, microseconds (even, 0..508; factory 0).
    clock : Clock, optional
        The plant's own sample clock (default the real one).
    period_s : float, optional
        The servo's own sample period; None: one sample per goal.

    Attributes
    ----------
    slot_source : callable or None
        In-process tests: returns the host's slot of the goal being written.
    on_event : callable or None
        Called with one line when the torque goes off or the servo restarts.
    """

    def __init__(
        self,
        servo_id: int = 1,
        *,
        servo: Servo | str = "sts3215",
        return_delay_us: int = 0,
        clock: Clock | None = None,
        period_s: float | None = None,
    ) -> None:
        delay = 2 * return_delay_units(servo_id, return_delay_us, max_id=253)
        self._clock: Clock = clock if clock is not None else MonotonicClock()
        self.servo, self._sampled = servo_plant(servo, period_s)
        self.slot_source: Callable[[], int | None] | None = None
        self.on_event: Callable[[str], None] | None = None
        self._memory = bytearray(ct.TABLE_SIZE)
        for f in ct.FIELDS:
            self._put(f, f.initial)
        self._put(ct.ID, servo_id)
        self._put(ct.RETURN_DELAY_TIME, delay // 2)
        self._saved_eeprom = bytes(self._memory[: ct.TORQUE_ENABLE.address])
        self._registered: tuple[int, bytes] | None = None
        #: Number of restarts (brown-outs).
        self.restarts = 0
        self._powered = False
        self._show()

    # ---- state -----------------------------------------------------------------------
    def value(self, field: Field) -> int:
        """The current value of an entry (signed where the entry is sign-magnitude)."""
        return ct.decode_value(field, self._memory, field.address)

    @property
    def id(self) -> int:
        return self.value(ct.ID)

    @property
    def torque(self) -> bool:
        return bool(self.value(ct.TORQUE_ENABLE))

    @property
    def error(self) -> int:
        """The status packets' error byte: the active protections (Status, 65)."""
        return self.value(ct.STATUS)

    @property
    def status_return_level(self) -> int:
        return self.value(ct.STATUS_RETURN_LEVEL)

    @property
    def return_delay_s(self) -> float:
        return self.value(ct.RETURN_DELAY_TIME) * ct.SECONDS_PER_RETURN_DELAY_UNIT

    @property
    def plant(self) -> SampledPlant:
        """The mechanics and their sample count."""
        return self._sampled

    @property
    def steps(self) -> int:
        """Samples the plant has advanced."""
        return self._sampled.index + 1

    def _put(self, field: Field, value: int) -> None:
        self._memory[field.address : field.end] = ct.encode_value(field, value)

    # ---- instructions ------------------------------------------------------------------
    def read(self, address: int, length: int) -> bytes | None:
        """READ: the bytes ``address .. address + length - 1``; None beyond the table (not answered).

        Parameters
        ----------
        address, length : int
            First byte and number of bytes.
        """
        if length < 1 or address < 0 or address + length > ct.TABLE_SIZE:
            return None
        return bytes(self._memory[address : address + length])

    def write(self, address: int, data: bytes) -> None:
        """WRITE: each writable entry the data covers whole takes its new value; the rest is ignored.

        Parameters
        ----------
        address : int
            First byte.
        data : bytes
            The bytes to write there.
        """
        end = address + len(data)
        if not data or address < 0 or end > ct.TABLE_SIZE:
            return
        torque_before = self.torque
        wrote_goal = False
        for f in ct.fields_in(address, len(data)):
            if not f.writable or f.address < address or f.end > end:
                continue
            value = ct.decode_value(f, data, f.address - address)
            if f is ct.GOAL_POSITION:
                value = min(max(value, self.value(ct.MIN_POSITION_LIMIT)), self.value(ct.MAX_POSITION_LIMIT))
                wrote_goal = True
            if f is ct.TORQUE_ENABLE and value and self.error & self.value(ct.UNLOADING_CONDITION):
                continue  # a protection that unloads keeps the torque off until it clears
            self._put(f, value)
            if f.eeprom and self.value(ct.LOCK) == 0:
                self._saved_eeprom = bytes(self._memory[: ct.TORQUE_ENABLE.address])
        if self.value(ct.LOCK) == 0 and address <= ct.LOCK.address < end:
            self._saved_eeprom = bytes(self._memory[: ct.TORQUE_ENABLE.address])
        self._follow_torque()
        if wrote_goal and torque_before and self.torque:
            self._step()

    def reg_write(self, address: int, data: bytes) -> None:
        """REG_WRITE: held until ACTION.

        Parameters
        ----------
        address : int
            First byte.
        data : bytes
            The bytes to write there on ACTION.
        """
        self._registered = (address, bytes(data))

    def action(self) -> None:
        """ACTION: apply the registered write (nothing when there is none)."""
        if self._registered is not None:
            address, data = self._registered
            self._registered = None
            self.write(address, data)

    def reset(self) -> None:
        """RESET: the memory table back to the factory's, the ID kept, saved as such."""
        servo_id = self.id
        for f in ct.FIELDS:
            if f.eeprom and f.writable:
                self._put(f, f.initial)
        self._put(ct.ID, servo_id)
        self._saved_eeprom = bytes(self._memory[: ct.TORQUE_ENABLE.address])

    # ---- faults --------------------------------------------------------------------------
    def restart(self) -> None:
        """A brown-out: the saved EEPROM and the SRAM's power-on values back, the torque off; the gear stays where it is."""
        self._memory[: ct.TORQUE_ENABLE.address] = self._saved_eeprom
        for f in ct.FIELDS:
            if not f.eeprom:
                self._put(f, f.initial)
        self._registered = None
        self._follow_torque()
        self._show()
        self._put(ct.GOAL_POSITION, self.value(ct.PRESENT_POSITION))
        self.restarts += 1
        self._event("restarted (brown-out): torque off")

    def inject_fault(self, bits: ErrorBit) -> None:
        """A protection trips: Status and every status packet show ``bits``; Unloading Condition's bits switch the torque off.

        Parameters
        ----------
        bits : ErrorBit
            The protections that trip.
        """
        self._put(ct.STATUS, self.error | int(bits))
        if self.error & self.value(ct.UNLOADING_CONDITION):
            self._put(ct.TORQUE_ENABLE, 0)
            self._follow_torque()

    # ---- the plant -------------------------------------------------------------------------
    def plant_input(self) -> float:
        """The plant input (rad) Goal Position stands for."""
        return (self.value(ct.GOAL_POSITION) - ct.POSITION_CENTRE) * ct.RAD_PER_COUNT

    def _follow_torque(self) -> None:
        was, self._powered = self._powered, self.torque
        if self.torque:
            self._sampled.enable()
        else:
            self._sampled.disable()
            if was:
                self._event("torque off")

    def _event(self, what: str) -> None:
        if self.on_event is not None:
            self.on_event(f"servo {self.id}: {what}")

    def _step(self) -> None:
        slot = self.slot_source() if self.slot_source is not None else None
        self._sampled.command(self.plant_input(), self._clock.now_ns(), slot=slot)
        self._show()

    def _show(self) -> None:
        """The plant's latest sample in the memory table's units."""
        y = self._sampled.plant.y
        self._put(ct.PRESENT_POSITION, _clip(ct.PRESENT_POSITION, round(y / ct.RAD_PER_COUNT) + ct.POSITION_CENTRE))
        twin = self._sampled.twin
        if twin is None:
            speed, load, current = self._sampled.velocity / ct.RAD_PER_S_PER_SPEED_UNIT, 0.0, 0.0
        else:
            r = twin.reading
            speed = r.velocity_rad_s / ct.RAD_PER_S_PER_SPEED_UNIT
            load = r.duty * 100.0 / ct.LOAD_PERCENT_PER_UNIT
            current = abs(r.current_a) / ct.AMPERE_PER_CURRENT_UNIT
        self._put(ct.PRESENT_SPEED, _clip(ct.PRESENT_SPEED, round(speed)))
        self._put(ct.PRESENT_LOAD, _clip(ct.PRESENT_LOAD, round(load)))
        self._put(ct.PRESENT_CURRENT, _clip(ct.PRESENT_CURRENT, round(current)))
        self._put(ct.MOVING, int(abs(self.value(ct.PRESENT_SPEED)) > 0))


def _clip(field: Field, value: int) -> int:
    return max(field.minimum, min(field.maximum, value))
