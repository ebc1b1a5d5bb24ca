"""The STS-series memory table (STS3215): addresses, sizes, the sign-magnitude encodings, units.

Numbers of two bytes are little-endian (STS/SMS). Signed entries are not
two's complement: the STS manual gives them as sign-magnitude, the sign in
one bit (bit 15 for positions, speeds and Goal Position; bit 11 for Homing
Offset; bit 10 for Present Load), the magnitude in the bits below it --
what the official SDK's ``scs_tohost(value, bit)`` / ``scs_toscs(value,
bit)`` decode and encode.

The EEPROM area (below Torque Enable, 40) keeps its values over a power
cycle only while Lock (55) is 0; the driver unlocks, writes and locks
again. Sources: Feetech STS3215 memory table (the ``SMS_STS`` table the SDK's
``sms_sts.py`` names: ``SMS_STS_GOAL_POSITION_L = 42``,
``SMS_STS_LOCK = 55``, ``SMS_STS_PRESENT_POSITION_L = 56``, ...) and the
table LeRobot ships for the STS3215 (``STS_SMS_SERIES_CONTROL_TABLE``,
``STS_SMS_SERIES_ENCODINGS_TABLE``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "Field",
    "FIELDS",
    "TABLE_SIZE",
    "encode_value",
    "decode_value",
    "fields_in",
    "BAUD_RATES",
    "COUNTS_PER_REV",
    "RAD_PER_COUNT",
    "POSITION_CENTRE",
    "RAD_PER_S_PER_SPEED_UNIT",
    "LOAD_PERCENT_PER_UNIT",
    "VOLT_PER_UNIT",
    "AMPERE_PER_CURRENT_UNIT",
    "SECONDS_PER_RETURN_DELAY_UNIT",
    "MODEL_NAMES",
    "PRESENT_BLOCK",
]


@dataclass(frozen=True)
class Field:
    """One entry of the memory table.

    Attributes
    ----------
    name : str
        The memory table's name.
    address, size : int
        First byte and length in bytes (1 or 2).
    writable : bool
        False for read-only entries.
    initial : int
        Value after power-on (factory value for EEPROM entries).
    sign_bit : int or None
        The bit that holds the sign of a sign-magnitude entry (15, 11 or 10); None: unsigned.
    """

    name: str
    address: int
    size: int
    writable: bool
    initial: int = 0
    sign_bit: int | None = None

    @property
    def end(self) -> int:
        """One past the last byte."""
        return self.address + self.size

    @property
    def eeprom(self) -> bool:
        """In the EEPROM area (kept over a power cycle only while unlocked)."""
        return self.address < TORQUE_ENABLE.address

    @property
    def minimum(self) -> int:
        return -((1 << self.sign_bit) - 1) if self.sign_bit is not None else 0

    @property
    def maximum(self) -> int:
        return (1 << self.sign_bit) - 1 if self.sign_bit is not None else (1 << (8 * self.size)) - 1


def _rw(name: str, address: int, size: int, initial: int = 0, sign_bit: int | None = None) -> Field:
    return Field(name, address, size, True, initial, sign_bit)


def _r(name: str, address: int, size: int, initial: int = 0, sign_bit: int | None = None) -> Field:
    return Field(name, address, size, False, initial, sign_bit)


# ---- EEPROM area (factory values of an STS3215, 7.4 V) ---------------------------------------------------------
FIRMWARE_MAJOR = _r("Firmware Major Version", 0, 1, 3)
FIRMWARE_MINOR = _r("Firmware Minor Version", 1, 1, 10)
MODEL_NUMBER = _r("Model Number", 3, 2, 777)  # 0x0309: STS3215
ID = _rw("ID", 5, 1, 1)
BAUD_RATE = _rw("Baud Rate", 6, 1, 0)  # 0: 1 Mbps
RETURN_DELAY_TIME = _rw("Return Delay Time", 7, 1, 0)  # 2 us a unit
STATUS_RETURN_LEVEL = _rw("Response Status Level", 8, 1, 1)  # 0: only READ and PING answered, 1: all
MIN_POSITION_LIMIT = _rw("Min Position Limit", 9, 2, 0)
MAX_POSITION_LIMIT = _rw("Max Position Limit", 11, 2, 4095)
MAX_TEMPERATURE_LIMIT = _rw("Max Temperature Limit", 13, 1, 70)  # degC
MAX_VOLTAGE_LIMIT = _rw("Max Input Voltage", 14, 1, 80)  # 0.1 V
MIN_VOLTAGE_LIMIT = _rw("Min Input Voltage", 15, 1, 40)
MAX_TORQUE_LIMIT = _rw("Max Torque Limit", 16, 2, 1000)  # 0.1 %
PHASE = _rw("Phase", 18, 1, 12)
UNLOADING_CONDITION = _rw("Unloading Condition", 19, 1, 44)  # protections that switch the torque off
LED_ALARM_CONDITION = _rw("LED Alarm Condition", 20, 1, 47)
P_COEFFICIENT = _rw("P Coefficient", 21, 1, 32)
D_COEFFICIENT = _rw("D Coefficient", 22, 1, 32)
I_COEFFICIENT = _rw("I Coefficient", 23, 1, 0)
MINIMUM_STARTUP_FORCE = _rw("Minimum Startup Force", 24, 2, 16)
CW_DEAD_ZONE = _rw("CW Dead Zone", 26, 1, 1)
CCW_DEAD_ZONE = _rw("CCW Dead Zone", 27, 1, 1)
PROTECTION_CURRENT = _rw("Protection Current", 28, 2, 500)
ANGULAR_RESOLUTION = _rw("Angular Resolution", 30, 1, 1)
HOMING_OFFSET = _rw("Homing Offset", 31, 2, 0, sign_bit=11)
OPERATING_MODE = _rw("Operating Mode", 33, 1, 0)  # 0: position servo mode
PROTECTIVE_TORQUE = _rw("Protective Torque", 34, 1, 20)
PROTECTION_TIME = _rw("Protection Time", 35, 1, 200)
OVERLOAD_TORQUE = _rw("Overload Torque", 36, 1, 80)
# ---- SRAM area ---------------------------------------------------------------------------------------------------
TORQUE_ENABLE = _rw("Torque Enable", 40, 1, 0)
ACCELERATION = _rw("Acceleration", 41, 1, 0)
GOAL_POSITION = _rw("Goal Position", 42, 2, 0, sign_bit=15)
GOAL_TIME = _rw("Goal Time", 44, 2, 0)
GOAL_SPEED = _rw("Goal Speed", 46, 2, 0, sign_bit=15)
TORQUE_LIMIT = _rw("Torque Limit", 48, 2, 1000)
LOCK = _rw("Lock", 55, 1, 1)
PRESENT_POSITION = _r("Present Position", 56, 2, 0, sign_bit=15)
PRESENT_SPEED = _r("Present Speed", 58, 2, 0, sign_bit=15)
PRESENT_LOAD = _r("Present Load", 60, 2, 0, sign_bit=10)  # 0.1 % of the maximum, the sign its direction
PRESENT_VOLTAGE = _r("Present Voltage", 62, 1, 74)  # 0.1 V
PRESENT_TEMPERATURE = _r("Present Temperature", 63, 1, 30)  # degC
STATUS = _r("Status", 65, 1, 0)  # the active protections, bits as the status error byte
MOVING = _r("Moving", 66, 1, 0)
PRESENT_CURRENT = _r("Present Current", 69, 2, 0)  # 6.5 mA a unit

FIELDS: tuple[Field, ...] = (
    FIRMWARE_MAJOR, FIRMWARE_MINOR, MODEL_NUMBER, ID, BAUD_RATE, RETURN_DELAY_TIME, STATUS_RETURN_LEVEL,
    MIN_POSITION_LIMIT, MAX_POSITION_LIMIT, MAX_TEMPERATURE_LIMIT, MAX_VOLTAGE_LIMIT, MIN_VOLTAGE_LIMIT,
    MAX_TORQUE_LIMIT, PHASE, UNLOADING_CONDITION, LED_ALARM_CONDITION, P_COEFFICIENT, D_COEFFICIENT,
    I_COEFFICIENT, MINIMUM_STARTUP_FORCE, CW_DEAD_ZONE, CCW_DEAD_ZONE, PROTECTION_CURRENT, ANGULAR_RESOLUTION,
    HOMING_OFFSET, OPERATING_MODE, PROTECTIVE_TORQUE, PROTECTION_TIME, OVERLOAD_TORQUE,
    TORQUE_ENABLE, ACCELERATION, GOAL_POSITION, GOAL_TIME, GOAL_SPEED, TORQUE_LIMIT, LOCK,
    PRESENT_POSITION, PRESENT_SPEED, PRESENT_LOAD, PRESENT_VOLTAGE, PRESENT_TEMPERATURE, STATUS, MOVING,
    PRESENT_CURRENT,
)  # fmt: skip
#: Bytes of the memory table the emulator holds.
TABLE_SIZE = 86

#: Baud Rate (6) value -> bit/s.
BAUD_RATES = {0: 1_000_000, 1: 500_000, 2: 250_000, 3: 128_000, 4: 115_200, 5: 76_800, 6: 57_600, 7: 38_400}

COUNTS_PER_REV = 4096
RAD_PER_COUNT = 2 * math.pi / COUNTS_PER_REV
#: Goal/Present Position of the middle of the range (0 rad).
POSITION_CENTRE = 2048
#: Present Speed: counts per second (50 steps/s per unit on some tables; the STS3215's is 1 count/s).
RAD_PER_S_PER_SPEED_UNIT = RAD_PER_COUNT
LOAD_PERCENT_PER_UNIT = 0.1
VOLT_PER_UNIT = 0.1
AMPERE_PER_CURRENT_UNIT = 0.0065
SECONDS_PER_RETURN_DELAY_UNIT = 2e-6
#: Model Number -> name.
MODEL_NAMES = {777: "STS3215", 2825: "STS3250", 1284: "SCS0009"}
#: The per-sample READ: Goal Position (42) to Present Current's end (71) in one transaction.
PRESENT_BLOCK = (GOAL_POSITION.address, PRESENT_CURRENT.end - GOAL_POSITION.address)


def fields_in(address: int, length: int) -> tuple[Field, ...]:
    """The fields that overlap the bytes ``address .. address + length - 1``."""
    end = address + length
    return tuple(f for f in FIELDS if f.address < end and f.end > address)


def encode_value(field: Field, value: int) -> bytes:
    """``value`` as the field's little-endian bytes (sign-magnitude for a signed field).

    Raises
    ------
    ValueError
        A value the field cannot hold.
    """
    value = int(value)
    if not field.minimum <= value <= field.maximum:
        raise ValueError(f"{field.name} (={value}) must be in {field.minimum}..{field.maximum}")
    raw = value if value >= 0 else (-value | 1 << field.sign_bit)  # type: ignore[operator]
    return raw.to_bytes(field.size, "little")


def decode_value(field: Field, data: bytes | bytearray | list[int], offset: int = 0) -> int:
    """The field's value from ``data``, where ``data[offset]`` is the field's first byte."""
    raw = int.from_bytes(bytes(data[offset : offset + field.size]), "little")
    bit = field.sign_bit
    if bit is None:
        return raw
    magnitude = raw & ((1 << bit) - 1)
    return -magnitude if raw >> bit & 1 else magnitude
