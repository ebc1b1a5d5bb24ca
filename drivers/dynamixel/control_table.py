"""The ROBOTIS X-series control table (Protocol 2.0): the one place for addresses, sizes and units.

Addresses, sizes, access and initial values are those of the XM430-W350
e-manual (https://emanual.robotis.com/docs/en/dxl/x/xm430-w350/); the other
X-series servos share the layout up to Present Temperature (146). Both the
driver and the emulator read them from here.

The EEPROM area (addresses below Torque Enable, 64) can only be written while
the torque is off; the servo answers an attempt with an Access Error.
Multi-byte values are little-endian; the fields marked ``signed`` hold two's
complement numbers (the SDK hands them back unsigned).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

__all__ = [
    "Field",
    "FIELDS",
    "TABLE_SIZE",
    "OperatingMode",
    "HardwareError",
    "BAUD_RATES",
    "MODEL_NAMES",
    "field_at",
    "fields_in",
    "encode_value",
    "decode_value",
    "POSITION_COUNTS_PER_TURN",
    "POSITION_CENTRE",
    "RAD_PER_COUNT",
    "AMPERE_PER_UNIT",
    "PERCENT_PER_PWM_UNIT",
    "RAD_PER_S_PER_VELOCITY_UNIT",
    "SECONDS_PER_RETURN_DELAY_UNIT",
    "SECONDS_PER_BUS_WATCHDOG_UNIT",
    "BUS_WATCHDOG_EXPIRED",
    "TICK_WRAP_S",
    "PRESENT_BLOCK",
]


@dataclass(frozen=True)
class Field:
    """One entry of the control table.

    Attributes
    ----------
    name : str
        The e-manual's name.
    address, size : int
        First byte and length in bytes.
    writable : bool
        False for read-only entries (Access Error when written).
    initial : int
        Value after power-on (factory default for EEPROM entries).
    signed : bool
        Whether the bytes hold a two's complement number.
    """

    name: str
    address: int
    size: int
    writable: bool
    initial: int = 0
    signed: bool = False

    @property
    def end(self) -> int:
        """One past the last byte."""
        return self.address + self.size

    @property
    def eeprom(self) -> bool:
        """In the EEPROM area: locked while the torque is on."""
        return self.address < TORQUE_ENABLE.address

    @property
    def minimum(self) -> int:
        return -(1 << (8 * self.size - 1)) if self.signed else 0

    @property
    def maximum(self) -> int:
        return (1 << (8 * self.size - 1)) - 1 if self.signed else (1 << (8 * self.size)) - 1


def _rw(name: str, address: int, size: int, initial: int = 0, signed: bool = False) -> Field:
    return Field(name, address, size, True, initial, signed)


def _r(name: str, address: int, size: int, initial: int = 0, signed: bool = False) -> Field:
    return Field(name, address, size, False, initial, signed)


# ---- EEPROM area ---------------------------------------------------------------------
MODEL_NUMBER = _r("Model Number", 0, 2, 1020)
MODEL_INFORMATION = _r("Model Information", 2, 4)
FIRMWARE_VERSION = _r("Firmware Version", 6, 1, 48)
ID = _rw("ID", 7, 1, 1)
BAUD_RATE = _rw("Baud Rate", 8, 1, 1)
RETURN_DELAY_TIME = _rw("Return Delay Time", 9, 1, 250)
DRIVE_MODE = _rw("Drive Mode", 10, 1)
OPERATING_MODE = _rw("Operating Mode", 11, 1, 3)
SECONDARY_ID = _rw("Secondary(Shadow) ID", 12, 1, 255)
PROTOCOL_TYPE = _rw("Protocol Type", 13, 1, 2)
HOMING_OFFSET = _rw("Homing Offset", 20, 4, 0, signed=True)
MOVING_THRESHOLD = _rw("Moving Threshold", 24, 4, 10)
TEMPERATURE_LIMIT = _rw("Temperature Limit", 31, 1, 80)
MAX_VOLTAGE_LIMIT = _rw("Max Voltage Limit", 32, 2, 160)
MIN_VOLTAGE_LIMIT = _rw("Min Voltage Limit", 34, 2, 95)
PWM_LIMIT = _rw("PWM Limit", 36, 2, 885)
CURRENT_LIMIT = _rw("Current Limit", 38, 2, 1193)
ACCELERATION_LIMIT = _rw("Acceleration Limit", 40, 4, 32767)
VELOCITY_LIMIT = _rw("Velocity Limit", 44, 4, 350)
MAX_POSITION_LIMIT = _rw("Max Position Limit", 48, 4, 4095)
MIN_POSITION_LIMIT = _rw("Min Position Limit", 52, 4, 0)
SHUTDOWN = _rw("Shutdown", 63, 1, 52)
# ---- RAM area --------------------------------------------------------------------------
TORQUE_ENABLE = _rw("Torque Enable", 64, 1)
LED = _rw("LED", 65, 1)
STATUS_RETURN_LEVEL = _rw("Status Return Level", 68, 1, 2)
REGISTERED_INSTRUCTION = _r("Registered Instruction", 69, 1)
HARDWARE_ERROR_STATUS = _r("Hardware Error Status", 70, 1)
VELOCITY_I_GAIN = _rw("Velocity I Gain", 76, 2, 1920)
VELOCITY_P_GAIN = _rw("Velocity P Gain", 78, 2, 100)
POSITION_D_GAIN = _rw("Position D Gain", 80, 2)
POSITION_I_GAIN = _rw("Position I Gain", 82, 2)
POSITION_P_GAIN = _rw("Position P Gain", 84, 2, 800)
FEEDFORWARD_2ND_GAIN = _rw("Feedforward 2nd Gain", 88, 2)
FEEDFORWARD_1ST_GAIN = _rw("Feedforward 1st Gain", 90, 2)
BUS_WATCHDOG = _rw("Bus Watchdog", 98, 1, 0, signed=True)  # 1..127 x 20 ms; -1: expired (Bus Watchdog Error)
GOAL_PWM = _rw("Goal PWM", 100, 2, 0, signed=True)
GOAL_CURRENT = _rw("Goal Current", 102, 2, 0, signed=True)
GOAL_VELOCITY = _rw("Goal Velocity", 104, 4, 0, signed=True)
PROFILE_ACCELERATION = _rw("Profile Acceleration", 108, 4)
PROFILE_VELOCITY = _rw("Profile Velocity", 112, 4)
GOAL_POSITION = _rw("Goal Position", 116, 4, 2048, signed=True)
REALTIME_TICK = _r("Realtime Tick", 120, 2)
MOVING = _r("Moving", 122, 1)
MOVING_STATUS = _r("Moving Status", 123, 1)
PRESENT_PWM = _r("Present PWM", 124, 2, 0, signed=True)
PRESENT_CURRENT = _r("Present Current", 126, 2, 0, signed=True)
PRESENT_VELOCITY = _r("Present Velocity", 128, 4, 0, signed=True)
PRESENT_POSITION = _r("Present Position", 132, 4, 2048, signed=True)
VELOCITY_TRAJECTORY = _r("Velocity Trajectory", 136, 4, 0, signed=True)
POSITION_TRAJECTORY = _r("Position Trajectory", 140, 4, 0, signed=True)
PRESENT_INPUT_VOLTAGE = _r("Present Input Voltage", 144, 2, 120)
PRESENT_TEMPERATURE = _r("Present Temperature", 146, 1, 36)

#: Every field, by address.
FIELDS: tuple[Field, ...] = tuple(
    sorted((v for v in dict(globals()).values() if isinstance(v, Field)), key=lambda f: f.address)
)

#: Bytes the emulator implements (the indirect-address area above 146 is not emulated).
TABLE_SIZE = PRESENT_TEMPERATURE.end

#: One READ of this block returns Realtime Tick, Present PWM/Current/Velocity/Position together.
PRESENT_BLOCK = (REALTIME_TICK.address, PRESENT_POSITION.end - REALTIME_TICK.address)


class OperatingMode(enum.IntEnum):
    """Values of Operating Mode (11)."""

    CURRENT = 0
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5
    PWM = 16


class HardwareError(enum.IntFlag):
    """Bits of Hardware Error Status (70) and Shutdown (63)."""

    INPUT_VOLTAGE = 1
    OVERHEATING = 4
    MOTOR_ENCODER = 8
    ELECTRICAL_SHOCK = 16
    OVERLOAD = 32

    def describe(self) -> str:
        """``"overload, overheating"`` (the names of the bits set), or ``"none"``."""
        names = [bit.name.lower().replace("_", " ") for bit in HardwareError if bit in self and bit.name]
        return ", ".join(names) if names else "none"


#: Baud Rate (8) register value -> bits per second.
BAUD_RATES: dict[int, int] = {
    0: 9600,
    1: 57600,
    2: 115200,
    3: 1_000_000,
    4: 2_000_000,
    5: 3_000_000,
    6: 4_000_000,
    7: 4_500_000,
}

#: Model Number -> name, for messages and model.json (others are shown by number).
MODEL_NAMES: dict[int, str] = {1020: "XM430-W350", 1030: "XM430-W210", 1060: "XL430-W250"}

# ---- units -------------------------------------------------------------------------------
#: Encoder counts per output turn (12-bit absolute encoder).
POSITION_COUNTS_PER_TURN = 4096
#: Present Position at the middle of the range: user position 0 rad.
POSITION_CENTRE = 2048
RAD_PER_COUNT = 2.0 * math.pi / POSITION_COUNTS_PER_TURN
#: Goal/Present Current unit: about 2.69 mA.
AMPERE_PER_UNIT = 2.69e-3
#: Goal/Present PWM unit: 885 units are 100 % (about 0.113 %).
PERCENT_PER_PWM_UNIT = 100.0 / 885.0
#: Present Velocity unit: 0.229 rev/min.
RAD_PER_S_PER_VELOCITY_UNIT = 0.229 * 2.0 * math.pi / 60.0
#: Return Delay Time unit: 2 us.
SECONDS_PER_RETURN_DELAY_UNIT = 2e-6
#: Bus Watchdog (98): 1..127 units of 20 ms (0: off); the servo sets -1 when it expired.
SECONDS_PER_BUS_WATCHDOG_UNIT = 0.02
BUS_WATCHDOG_EXPIRED = -1
#: The Realtime Tick counts milliseconds 0..32767 and wraps.
TICK_WRAP_S = 32.768

_BY_ADDRESS = {f.address: f for f in FIELDS}


def field_at(address: int) -> Field | None:
    """The field that starts at ``address``, or None."""
    return _BY_ADDRESS.get(address)


def fields_in(address: int, length: int) -> tuple[Field, ...]:
    """The fields that overlap the bytes ``address .. address + length - 1``."""
    end = address + length
    return tuple(f for f in FIELDS if f.address < end and f.end > address)


def encode_value(field: Field, value: int) -> bytes:
    """``value`` as the field's little-endian bytes (two's complement when signed)."""
    return int(value).to_bytes(field.size, "little", signed=field.signed)


def decode_value(field: Field, data: bytes | bytearray | list[int], offset: int = 0) -> int:
    """The field's value from ``data``, where ``data[offset]`` is the field's first byte."""
    return int.from_bytes(bytes(data[offset : offset + field.size]), "little", signed=field.signed)
