"""The CiA 402 object dictionary both sides of the bus use, and the profile's numbers.

One place for the CANopen facts servoid relies on: the objects of CiA 301
(communication) and CiA 402 (drives and motion control) that the driver
configures and the simulated drive serves, with their data types and access,
and the state machine's statusword patterns and controlword commands.

The state machine itself is canopen's (:class:`canopen.profiles.p402.State402`:
statusword masks, the transition table); this module only names what servoid
needs from it. canopen is imported when a dictionary is built, not before.

Objects (index, meaning, type)::

    0x1000 device type           U32  (low 16 bits 402 = 0x192 for a drive)
    0x1001 error register        U8
    0x1006 communication cycle period  U32  us (the SYNC interval; 0: not used)
    0x1008/0x1009/0x100A device name, hardware and software version (strings)
    0x1016 consumer heartbeat time  U32 (sub 1): node id in bits 16..23, time in ms in bits 0..15 (0: off)
    0x1017 producer heartbeat    U16  ms
    0x1018 identity              vendor id, product code, revision, serial (U32)
    0x1019 synchronous counter overflow value  U8  (0: SYNC without counter; 2..240)
    0x1400..0x1403 / 0x1600..    RPDO communication / mapping
    0x1800..0x1803 / 0x1A00..    TPDO communication / mapping
    0x6007 abort connection option code  I16  (what a heartbeat loss does: 0 nothing, 1 fault,
                                 2 disable voltage, 3 quick stop)
    0x603F error code            U16  (the EMCY code of the active fault)
    0x6040 controlword           U16
    0x6041 statusword            U16
    0x6060 / 0x6061 mode of operation / display   I8 (8 CSP, 10 CST)
    0x6064 position actual value I32  increments
    0x6071 target torque         I16  per mille of the rated torque
    0x6076 motor rated torque    U32  mNm
    0x6077 torque actual value   I16  per mille of the rated torque
    0x607A target position       I32  increments
    0x608F position encoder resolution: increments (sub 1) per motor revolutions (sub 2)
    0x6091 gear ratio            motor shaft revolutions (sub 1) per driving shaft revolutions (sub 2)
    0x60E4 additional position actual value  I32  (sub 1: a second encoder's increments)
    0x60E6 / 0x60EB additional position encoder resolution: increments (sub 1) / motor revolutions (sub 1)
    0x6502 supported drive modes U32  (bit 7 CSP, bit 9 CST)

Units: 0x6064 and 0x607A count the increments of the encoder the position
loop closes on, 0x608F says how many there are per motor revolutions; a
drive with a gear between motor and load says its ratio in 0x6091; a drive
with a second encoder (a load encoder behind the gear) reports it in 0x60E4
sub 1, its resolution in 0x60E6 / 0x60EB sub 1. Position in radians at the
driving (output) shaft is ``increments * 2 pi * motor revolutions /
(increments per those revolutions * gear ratio)``.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

from servoid.drivers.can._bus import import_vendor

__all__ = [
    "DEVICE_TYPE_402",
    "SYNC_COUNTER_OVERFLOW",
    "MODES",
    "SUPPORTED_MODE_BITS",
    "EMCY_COMMUNICATION",
    "CW_FAULT_RESET",
    "ABORT_OPTIONS",
    "heartbeat_consumer",
    "object_dictionary",
    "gear_fraction",
    "state_of",
    "statusword_of",
    "emcy_text",
]

#: Device type of a CiA 402 servo drive: profile 402 in the low word, "servo drive" (2) above it.
DEVICE_TYPE_402 = 0x0002_0192

#: Overflow value of the SYNC counter servoid configures (0x1019): the largest CiA 301 allows.
SYNC_COUNTER_OVERFLOW = 240

#: servoid's mode name -> CiA 402 mode of operation (0x6060): cyclic synchronous position / torque.
MODES = {"position": 8, "torque": 10}

#: Mode of operation -> its bit in "supported drive modes" (0x6502).
SUPPORTED_MODE_BITS = {8: 1 << 7, 10: 1 << 9}

#: EMCY code a drive sends when its master stops talking to it (CiA 301: heartbeat / life guard error).
EMCY_COMMUNICATION = 0x8130

#: Controlword bit 7: a rising edge resets a fault (transition 15).
CW_FAULT_RESET = 0x0080

#: Abort connection option code (0x6007): what the drive does when its master's heartbeat is lost.
ABORT_OPTIONS = {0: "no action", 1: "fault", 2: "disable voltage", 3: "quick stop"}


def heartbeat_consumer(node: int, time_ms: int) -> int:
    """The value of 0x1016 sub 1 that watches ``node``'s heartbeat with ``time_ms`` (CiA 301)."""
    return (node & 0x7F) << 16 | (time_ms & 0xFFFF)


def _p402() -> Any:
    return import_vendor("canopen.profiles.p402")


def state_of(statusword: int) -> str:
    """The CiA 402 state a statusword shows (``"OPERATION ENABLED"``, ``"FAULT"``, ...)."""
    for state, (mask, value) in _p402().State402.SW_MASK.items():
        if statusword & mask == value:
            return str(state)
    return "UNKNOWN"


def statusword_of(state: str) -> int:
    """The statusword bits that show ``state`` (the pattern of canopen's table)."""
    return int(_p402().State402.SW_MASK[state][1])


def emcy_text(code: int, register: int | None = None) -> str:
    """``"EMCY 0x2310 (current)"`` with canopen's description of the code's class."""
    canopen = import_vendor("canopen")
    error = canopen.emcy.EmcyError(code, register or 0, b"", 0.0)
    desc = error.get_desc()
    text = f"EMCY 0x{code:04X}" + (f" ({desc.lower()})" if desc else "")
    if register:
        text += f", error register 0x{register:02X}"
    return text


def gear_fraction(ratio: float) -> tuple[int, int]:
    """A gear ratio as whole motor shaft and driving shaft revolutions (0x6091): 353.5 -> (707, 2).

    Parameters
    ----------
    ratio : float
        Motor revolutions per driving shaft revolution, > 0.
    """
    fraction = Fraction(ratio).limit_denominator(1000)
    return fraction.numerator, fraction.denominator


def object_dictionary(node: int, *, additional: bool = True) -> Any:
    """The object dictionary of a CiA 402 drive with ``node`` as its node id.

    Parameters
    ----------
    node : int
        Node id.
    additional : bool
        Include the objects of a second encoder (0x60E4, 0x60E6, 0x60EB): a
        master's dictionary lists them so that it can map them; a drive has
        them only when it has the encoder.

    Returns
    -------
    canopen.ObjectDictionary
        The objects listed in the module docstring, with CiA 301's
        predefined connection set as defaults (RPDOn at ``0x100 * (n + 1) + node``,
        TPDOn at ``0x100 * n + 0x80 + node``), PDOs 2-4 off.
    """
    canopen = import_vendor("canopen")
    od_mod = canopen.objectdictionary
    dictionary = canopen.ObjectDictionary()
    dictionary.node_id = node

    def var(name: str, index: int, subindex: int, data_type: int, access: str, default: Any = None,
            mappable: bool = False) -> Any:  # fmt: skip
        v = od_mod.ODVariable(name, index, subindex)
        v.data_type = data_type
        v.access_type = access
        v.default = default
        v.pdo_mappable = mappable
        return v

    def record(name: str, index: int, members: list[tuple[str, int, str, Any]]) -> Any:
        rec = od_mod.ODRecord(name, index)
        rec.add_member(var("Highest sub-index supported", index, 0, od_mod.UNSIGNED8, "ro", len(members)))
        for sub, (member, data_type, access, default) in enumerate(members, start=1):
            rec.add_member(var(member, index, sub, data_type, access, default))
        return rec

    U8, U16, U32 = od_mod.UNSIGNED8, od_mod.UNSIGNED16, od_mod.UNSIGNED32
    I8, I16, I32 = od_mod.INTEGER8, od_mod.INTEGER16, od_mod.INTEGER32
    STR = od_mod.VISIBLE_STRING
    add = dictionary.add_object

    add(var("Device type", 0x1000, 0, U32, "ro", DEVICE_TYPE_402))
    add(var("Error register", 0x1001, 0, U8, "ro", 0))
    add(var("Communication cycle period", 0x1006, 0, U32, "rw", 0))
    add(var("Manufacturer device name", 0x1008, 0, STR, "const", ""))
    add(var("Manufacturer hardware version", 0x1009, 0, STR, "const", ""))
    add(var("Manufacturer software version", 0x100A, 0, STR, "const", ""))
    add(record("Consumer heartbeat time", 0x1016, [("Consumer heartbeat time 1", U32, "rw", 0)]))
    add(var("Producer heartbeat time", 0x1017, 0, U16, "rw", 0))
    add(record("Identity object", 0x1018, [
        ("Vendor-ID", U32, "ro", 0), ("Product code", U32, "ro", 0),
        ("Revision number", U32, "ro", 0), ("Serial number", U32, "ro", 0),
    ]))  # fmt: skip
    add(var("Synchronous counter overflow value", 0x1019, 0, U8, "rw", 0))
    invalid = 1 << 31
    for n in range(4):
        enabled = n == 0
        rx_cob = 0x200 + 0x100 * n + node
        tx_cob = 0x180 + 0x100 * n + node
        add(record(f"RPDO{n + 1} communication parameter", 0x1400 + n, [
            ("COB-ID", U32, "rw", rx_cob if enabled else rx_cob | invalid),
            ("Transmission type", U8, "rw", 1),
        ]))  # fmt: skip
        add(
            record(
                f"RPDO{n + 1} mapping parameter",
                0x1600 + n,
                [(f"Mapped object {i}", U32, "rw", 0) for i in range(1, 9)],
            )
        )
        add(record(f"TPDO{n + 1} communication parameter", 0x1800 + n, [
            ("COB-ID", U32, "rw", tx_cob if enabled else tx_cob | invalid),
            ("Transmission type", U8, "rw", 1),
            ("Inhibit time", U16, "rw", 0),
            ("Reserved", U8, "rw", 0),
            ("Event timer", U16, "rw", 0),
        ]))  # fmt: skip
        add(
            record(
                f"TPDO{n + 1} mapping parameter",
                0x1A00 + n,
                [(f"Mapped object {i}", U32, "rw", 0) for i in range(1, 9)],
            )
        )
        # an empty mapping: sub 0 counts the mapped objects and is writable
        for index in (0x1600 + n, 0x1A00 + n):
            sub0 = dictionary[index][0]
            sub0.access_type, sub0.default = "rw", 0
    add(var("Abort connection option code", 0x6007, 0, I16, "rw", 1))
    add(var("Error code", 0x603F, 0, U16, "ro", 0, mappable=True))
    add(var("Controlword", 0x6040, 0, U16, "rw", 0, mappable=True))
    add(var("Statusword", 0x6041, 0, U16, "ro", 0, mappable=True))
    add(var("Modes of operation", 0x6060, 0, I8, "rw", 0, mappable=True))
    add(var("Modes of operation display", 0x6061, 0, I8, "ro", 0, mappable=True))
    add(var("Position actual value", 0x6064, 0, I32, "ro", 0, mappable=True))
    add(var("Target torque", 0x6071, 0, I16, "rw", 0, mappable=True))
    add(var("Motor rated torque", 0x6076, 0, U32, "rw", 1000))
    add(var("Torque actual value", 0x6077, 0, I16, "ro", 0, mappable=True))
    add(var("Target position", 0x607A, 0, I32, "rw", 0, mappable=True))
    add(record("Position encoder resolution", 0x608F, [
        ("Encoder increments", U32, "rw", 0), ("Motor revolutions", U32, "rw", 1),
    ]))  # fmt: skip
    add(record("Gear ratio", 0x6091, [
        ("Motor shaft revolutions", U32, "rw", 1), ("Driving shaft revolutions", U32, "rw", 1),
    ]))  # fmt: skip
    if additional:
        actual = record(
            "Additional position actual value", 0x60E4, [("Additional position actual value 1", I32, "ro", 0)]
        )
        actual[1].pdo_mappable = True
        add(actual)
        add(record("Additional position encoder resolution - encoder increments", 0x60E6,
                   [("Encoder increments 1", U32, "rw", 0)]))  # fmt: skip
        add(record("Additional position encoder resolution - motor revolutions", 0x60EB,
                   [("Motor revolutions 1", U32, "rw", 1)]))  # fmt: skip
    add(var("Supported drive modes", 0x6502, 0, U32, "ro", sum(SUPPORTED_MODE_BITS.values())))
    return dictionary
