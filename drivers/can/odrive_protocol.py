"""ODrive "CAN Simple": message ids, payloads and names, for the driver and the simulated axis.

Source: the ODrive CAN protocol documentation --
https://github.com/odriverobotics/ODrive/blob/master/docs/can-protocol.rst and
its message table ``docs/_static/can-protocol.csv`` (firmware 0.5.x), and
https://docs.odriverobotics.com/v/latest/manual/can-protocol.html (firmware
0.6.x, ODrive Pro / S1). The facts used here hold for both:

* arbitration id = ``node_id << 5 | cmd_id`` (11-bit: node 0..63, command 0..31);
* all multi-byte values little-endian, floats IEEE 754 single precision;
* "Get" messages are requested with a remote (RTR) frame of the same id and
  answered with a data frame of that id;
* positions in turns, velocities in turns/s, torques in Nm;
* Set_Input_Pos carries ``Input_Pos`` (float32), ``Vel_FF`` (int16, 0.001
  turn/s) and ``Torque_FF`` (int16, 0.001 Nm).

Arbitrary settings (firmware 0.6): RxSdo (0x004) reads (opcode 0) or writes
(opcode 1) the endpoint ``id`` -- ``opcode u8, id u16, reserved u8, value``
(4 bytes, little-endian) -- and a read is answered by TxSdo (0x005:
``reserved u8, id u16, reserved u8, value``). Endpoint ids change with every
firmware build: they come from the board's ``flat_endpoints.json``
(``{"fw_version": ..., "endpoints": {"axis0.config.watchdog_timeout": {"id":
..., "type": "float"}, ...}}``), never from a table here.

The heartbeat (0x001) starts with ``Axis_Error`` (u32) and ``Axis_State``
(u8) in both firmware lines; the bytes after differ (0.5: error flags, 0.6:
procedure result and trajectory-done flag) and are not used. Axis error
names are those of firmware 0.6 (:data:`AXIS_ERRORS`); messages always give
the hex code as well, to look up in the 0.5 table on older boards.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = [
    "GET_VERSION",
    "HEARTBEAT",
    "ESTOP",
    "GET_ERROR",
    "SET_AXIS_STATE",
    "GET_ENCODER_ESTIMATES",
    "SET_CONTROLLER_MODE",
    "SET_INPUT_POS",
    "SET_INPUT_TORQUE",
    "CLEAR_ERRORS",
    "IDLE",
    "CLOSED_LOOP_CONTROL",
    "CONTROL_MODES",
    "INPUT_MODE_PASSTHROUGH",
    "AXIS_STATES",
    "AXIS_ERRORS",
    "arbitration_id",
    "split_id",
    "node_filter",
    "Heartbeat",
    "error_names",
    "state_name",
    "HEARTBEAT_FORMAT",
    "ESTIMATES_FORMAT",
    "INPUT_POS_FORMAT",
    "INPUT_TORQUE_FORMAT",
    "AXIS_STATE_FORMAT",
    "CONTROLLER_MODE_FORMAT",
    "ERROR_FORMAT",
    "VERSION_FORMAT",
    "RXSDO",
    "TXSDO",
    "SDO_FORMAT",
    "SDO_READ",
    "SDO_WRITE",
    "WATCHDOG_TIMER_EXPIRED",
    "WATCHDOG_ENDPOINTS",
    "sdo_value",
    "sdo_decode",
]

GET_VERSION = 0x000  # 0.6: protocol, hardware and firmware versions (0.5 reserves 0x000 for CANopen NMT)
HEARTBEAT = 0x001
ESTOP = 0x002
GET_ERROR = 0x003  # 0.6: active errors, disarm reason
RXSDO = 0x004  # 0.6: read or write an endpoint by id
TXSDO = 0x005  # 0.6: the answer to an endpoint read
SET_AXIS_STATE = 0x007
GET_ENCODER_ESTIMATES = 0x009
SET_CONTROLLER_MODE = 0x00B
SET_INPUT_POS = 0x00C
SET_INPUT_TORQUE = 0x00E
CLEAR_ERRORS = 0x018

IDLE = 1
CLOSED_LOOP_CONTROL = 8

#: servoid's mode name -> ODrive control mode (Set_Controller_Mode).
CONTROL_MODES = {"torque": 1, "position": 3}

#: Input mode that applies each input as it arrives (no filter, no trajectory).
INPUT_MODE_PASSTHROUGH = 1

AXIS_STATES = {
    0: "UNDEFINED", 1: "IDLE", 2: "STARTUP_SEQUENCE", 3: "FULL_CALIBRATION_SEQUENCE", 4: "MOTOR_CALIBRATION",
    6: "ENCODER_INDEX_SEARCH", 7: "ENCODER_OFFSET_CALIBRATION", 8: "CLOSED_LOOP_CONTROL", 9: "LOCKIN_SPIN",
    10: "ENCODER_DIR_FIND", 11: "HOMING", 12: "ENCODER_HALL_POLARITY_CALIBRATION",
    13: "ENCODER_HALL_PHASE_CALIBRATION", 14: "ANTICOGGING_CALIBRATION",
}  # fmt: skip

#: Axis error bits of firmware 0.6 (ODrive Pro / S1).
AXIS_ERRORS = {
    0x1: "INITIALIZING", 0x2: "SYSTEM_LEVEL", 0x4: "TIMING_ERROR", 0x8: "MISSING_ESTIMATE", 0x10: "BAD_CONFIG",
    0x20: "DRV_FAULT", 0x40: "MISSING_INPUT", 0x100: "DC_BUS_OVER_VOLTAGE", 0x200: "DC_BUS_UNDER_VOLTAGE",
    0x400: "DC_BUS_OVER_CURRENT", 0x800: "DC_BUS_OVER_REGEN_CURRENT", 0x1000: "CURRENT_LIMIT_VIOLATION",
    0x2000: "MOTOR_OVER_TEMP", 0x4000: "INVERTER_OVER_TEMP", 0x8000: "VELOCITY_LIMIT_VIOLATION",
    0x10000: "POSITION_LIMIT_VIOLATION", 0x1000000: "WATCHDOG_TIMER_EXPIRED", 0x2000000: "ESTOP_REQUESTED",
    0x4000000: "SPINOUT_DETECTED", 0x8000000: "BRAKE_RESISTOR_DISARMED", 0x10000000: "THERMISTOR_DISCONNECTED",
    0x40000000: "CALIBRATION_ERROR",
}  # fmt: skip

HEARTBEAT_FORMAT = struct.Struct("<IBBBB")  # axis error, axis state, then firmware-specific bytes
ESTIMATES_FORMAT = struct.Struct("<ff")  # position (turns), velocity (turns/s)
INPUT_POS_FORMAT = struct.Struct("<fhh")  # position (turns), vel_ff (0.001 turn/s), torque_ff (0.001 Nm)
INPUT_TORQUE_FORMAT = struct.Struct("<f")  # Nm
AXIS_STATE_FORMAT = struct.Struct("<I")
CONTROLLER_MODE_FORMAT = struct.Struct("<II")  # control mode, input mode
ERROR_FORMAT = struct.Struct("<II")  # active errors, disarm reason
VERSION_FORMAT = struct.Struct("<8B")  # protocol, hw major/minor/variant, fw major/minor/revision/unreleased
SDO_FORMAT = struct.Struct("<BHB4s")  # opcode (RxSdo) or reserved (TxSdo), endpoint id, reserved, value
SDO_READ, SDO_WRITE = 0, 1

#: Axis error bit the axis watchdog sets when it expires (firmware 0.6).
WATCHDOG_TIMER_EXPIRED = 0x1000000

#: The endpoints of the axis watchdog: its timeout (s) and whether it is on.
WATCHDOG_ENDPOINTS = ("axis0.config.watchdog_timeout", "axis0.config.enable_watchdog")

_SDO_TYPES = {"float": "<f", "bool": "<?", "uint8": "<B", "uint16": "<H", "uint32": "<I", "int32": "<i"}


def sdo_value(kind: str, value: float | bool | int) -> bytes:
    """``value`` as the 4 value bytes of an RxSdo write of an endpoint of type ``kind``."""
    return struct.pack(_SDO_TYPES[kind], value).ljust(4, b"\0")


def sdo_decode(kind: str, data: bytes) -> float | bool | int:
    """The value in the 4 value bytes of a TxSdo, for an endpoint of type ``kind``."""
    fmt = _SDO_TYPES[kind]
    return struct.unpack_from(fmt, data)[0]  # type: ignore[no-any-return]


_NODE_MASK = 0x7E0


def arbitration_id(node: int, command: int) -> int:
    """``node << 5 | command``."""
    return node << 5 | command


def split_id(arbitration: int) -> tuple[int, int]:
    """(node, command) of an arbitration id."""
    return arbitration >> 5, arbitration & 0x1F


def node_filter(node: int) -> list[dict[str, int | bool]]:
    """python-can receive filter that passes the frames of one node (all 32 commands)."""
    return [{"can_id": node << 5, "can_mask": _NODE_MASK, "extended": False}]


@dataclass(frozen=True)
class Heartbeat:
    """The part of the heartbeat both firmware lines share.

    Attributes
    ----------
    axis_error : int
        Axis error bits (0: none).
    axis_state : int
        Current axis state (1 idle, 8 closed loop control, ...).
    """

    axis_error: int
    axis_state: int

    @classmethod
    def decode(cls, data: bytes) -> Heartbeat:
        error, state = struct.unpack_from("<IB", data)
        return cls(axis_error=error, axis_state=state)

    def encode(self) -> bytes:
        return HEARTBEAT_FORMAT.pack(self.axis_error, self.axis_state, 0, 0, 0)

    def describe(self) -> str:
        text = f"axis state {state_name(self.axis_state)}"
        if self.axis_error:
            text = f"axis error 0x{self.axis_error:08X} ({error_names(self.axis_error)}), " + text
        return text


def error_names(code: int) -> str:
    """``"DC_BUS_OVER_VOLTAGE|MOTOR_OVER_TEMP"`` for an axis error code (unknown bits as hex)."""
    if not code:
        return "none"
    names = [name for bit, name in AXIS_ERRORS.items() if code & bit]
    rest = code & ~sum(bit for bit in AXIS_ERRORS if code & bit)
    if rest:
        names.append(f"0x{rest:X}")
    return "|".join(names)


def state_name(state: int) -> str:
    return AXIS_STATES.get(state, f"state {state}")
