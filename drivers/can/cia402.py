"""A CANopen CiA 402 servo drive in cyclic synchronous position or torque mode, through canopen.

Opening (:meth:`Cia402Driver._open`), all by SDO while the drive is
PRE-OPERATIONAL:

1. read the device type (0x1000): no answer is :class:`~servoid.errors.DriverTimeout`,
   a profile other than 402 is :class:`~servoid.errors.ProtocolError`;
2. check the mode is supported (0x6502), switch a drive left enabled off,
   set the mode of operation (0x6060: 8 CSP or 10 CST) and read it back (0x6061);
3. read the encoder resolution (0x608F) unless ``counts_per_rev`` is given,
   the gear ratio (0x6091, 1:1 if the drive has none), the second encoder
   (0x60E4 sub 0; its resolution 0x60E6 / 0x60EB sub 1) if it has one, and
   in torque mode the rated torque (0x6076);
4. map RPDO1 = controlword + target position (or target torque) and
   TPDO1 = statusword + the measured position (``encoder``: the additional
   position actual value 0x60E4 sub 1, a load encoder on the output, when
   the drive has one; else the position actual value 0x6064, the encoder
   the drive's loop closes on), both synchronous (transmission type 1), and
   switch PDOs 2-4 off;
5. configure the SYNC counter (0x1019 = 240; a drive without one gets plain SYNCs);
6. the drive's watchdog on its master (``watchdog``, default 0.5 s; 0: off): the
   abort connection option (0x6007) is "disable voltage", and the driver
   sends its heartbeat as node ``host_node`` (default 127) every quarter of
   the time, from python-can's cyclic sender, until it closes; from each
   torque-on to the next torque-off the heartbeat consumer (0x1016) watches
   it. A host killed with SIGKILL, hung, or cut off leaves the drive without
   heartbeat: it switches its power stage off within the time, and reports
   EMCY 0x8130;
7. NMT start (OPERATIONAL).

Each cyclic exchange is RPDO1 then SYNC, answered by TPDO1: the drive
applies the target on the SYNC and reports the statusword and the actual
position it measured. The SYNC carries a counter (CiA 301), advanced by the
number of the sampling session's slots since the previous exchange: a slot
the session skipped is a SYNC that never came, and the counter's gap tells
the drive how many of its cycles ran on the held target, so that its
samples follow the session's slots exactly. The session's period goes to
the communication cycle period (0x1006) as well. Torque on walks the state machine (Switch On Disabled
-> Ready to Switch On -> Switched On -> Operation Enabled) through the same
cycle, holding the target on the actual position so nothing jumps; torque
off is "disable voltage" (transition 9), confirmed by the statusword.

Errors: an EMCY from the drive, or a statusword that leaves Operation
Enabled during the run, is :class:`~servoid.errors.DeviceFault` (with the EMCY
code and 0x603F error code); no TPDO within ``timeout`` after a SYNC is
:class:`~servoid.errors.DriverTimeout`; a boot-up message from the drive
(it reset: power stage off, configuration lost) is
:class:`~servoid.errors.DeviceRestarted`. Closing switches the torque off and
sends the drive back to PRE-OPERATIONAL.

Units: positions in encoder increments (native), radians at the driving
(output) shaft for the user: increments through the encoder's resolution
(per motor revolutions) and the gear ratio; the target position counts
increments of the loop's encoder (0x607A, as 0x6064), which may not be the
one read. Torques in per mille of the rated torque (native), Nm for the
user. The driver has no device clock to offer (``device_time`` is None).
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

from servoid import readings_side, validation
from servoid.drivers.base import Limits, Option, Reading, UnitConversion
from servoid.drivers.can import cia402_od as profile
from servoid.drivers.can._bus import import_vendor
from servoid.drivers.can.driver import DEFAULT_NODES, DEFAULT_TIMEOUT_S, CanDriver, parse_bool
from servoid.errors import ConfigError, DeviceFault, DeviceRestarted, DriverError, DriverTimeout, ProtocolError

__all__ = ["Cia402Driver"]

log = logging.getLogger("servoid.drivers.can")

_OE = "OPERATION ENABLED"

#: State -> the controlword that moves it one step towards Operation Enabled.
_TOWARDS_ENABLED = {
    "SWITCH ON DISABLED": 0x0006,  # shutdown (2)
    "READY TO SWITCH ON": 0x0007,  # switch on (3)
    "SWITCHED ON": 0x000F,  # enable operation (4)
    "QUICK STOP ACTIVE": 0x0000,  # disable voltage (12), then up again
    "NOT READY TO SWITCH ON": 0x0000,  # wait for the drive's own transition 1
    "FAULT REACTION ACTIVE": 0x0000,  # wait for transition 14
}
_ENABLE_OPERATION = 0x000F
_DISABLE_VOLTAGE = 0x0000
_POWERED = ("OPERATION ENABLED", "QUICK STOP ACTIVE", "SWITCHED ON")
_INT32 = (-(1 << 31), (1 << 31) - 1)
_INT16 = (-(1 << 15), (1 << 15) - 1)
_NMT_OPERATIONAL, _NMT_PRE_OPERATIONAL = 0x01, 0x80


#: ``encoder=`` choices: which position the driver reads.
ENCODERS = ("auto", "main", "additional")

#: Heartbeat consumer time the driver gives the drive, s (URL ``watchdog``): far above any
#: scheduling stall of a healthy host, well below what a runaway servo should get.
DEFAULT_WATCHDOG_S = 0.5

#: Node id of the host's heartbeat (URL ``host_node``): the highest, which drives rarely take.
DEFAULT_HOST_NODE = 127


def _watchdog(text: str) -> float:
    seconds = float(text)
    if not (0 <= seconds <= 65.535):
        raise ValueError("the heartbeat consumer time is 0 (off) .. 65.535 s")
    return round(seconds * 1000) / 1000


def _node(text: str) -> int:
    value = int(text)
    if not 1 <= value <= 127:
        raise ValueError("a CANopen node id is 1..127")
    return value


def _counts(text: str) -> int:
    value = int(text)
    if value < 1:
        raise ValueError("must be >= 1")
    return value


def _encoder(text: str) -> str:
    if text not in ENCODERS:
        raise ValueError(f"choose one of {', '.join(ENCODERS)}")
    return text


class Cia402Driver(CanDriver):
    """A CiA 402 drive over CANopen (see the module docstring).

    Parameters
    ----------
    interface, channel, node, mode, bitrate, port, bind, timeout, limits
        As for :class:`~servoid.drivers.can.driver.CanDriver`; node 1..127.
    counts_per_rev : int, optional
        Increments per revolution of the loop's encoder; default: read from the drive (0x608F).
    encoder : {"auto", "main", "additional"}
        The position read: ``main`` the position actual value (0x6064, the
        encoder the drive's loop closes on), ``additional`` the additional
        position actual value 1 (0x60E4 sub 1, a second encoder, e.g. on the
        load behind the gear), ``auto`` (default) the additional one when the
        drive has it: the output is what identification wants to see.
    fault_reset : bool
        Reset a drive found in FAULT when switching the torque on (controlword
        bit 7); default False, which reports the fault instead.
    watchdog : float
        Seconds without the host's heartbeat after which the drive switches
        its power stage off (CiA 301 heartbeat consumer, whole ms up to 65.535 s;
        0: off).
    host_node : int
        Node id the host's heartbeat is sent as (1..127, not the drive's).
    readings : {"output", "motor"}
        Which shaft the position read is of (:attr:`~servoid.drivers.base.Driver.readings_side`):
        ``output`` (default: a load encoder, as ``encoder=auto`` reads on this project's emulator, or a
        drive whose one encoder is on the output), or ``motor`` for a drive whose 0x6064 is the motor
        encoder and no load encoder is read. The drive does not say which over CANopen (0x60E4 and
        dual-loop settings are vendor-specific); the play between motor and output is not in a
        record read on the motor, and identification says so.
    """

    protocol = "cia402"
    carries_slots: ClassVar[bool] = True  # the SYNC counter (0x1019) carries the session's slots
    watchdog_fed_by_exchanges: ClassVar[bool] = False  # the heartbeat thread feeds it, whatever the sample rate
    options: ClassVar[Mapping[str, Option]] = {
        **CanDriver.options,
        "counts_per_rev": Option(_counts, "encoder increments per revolution (default: the drive's 0x608F)"),
        "encoder": Option(
            _encoder, "position read: auto (default: 0x60E4 sub 1 if the drive has it, else 0x6064), main or additional"
        ),
        "fault_reset": Option(parse_bool, "reset a drive found in FAULT on enable: 1 or 0 (default 0)"),
        "watchdog": Option(
            _watchdog,
            f"s without the host's heartbeat before the drive switches off, 0: off (default {DEFAULT_WATCHDOG_S:g})",
        ),
        "host_node": Option(_node, "node id of the host's heartbeat, 1..127 (default 127)"),
    }

    def __init__(
        self,
        *,
        interface: str,
        channel: str = "",
        node: int = DEFAULT_NODES["cia402"],
        mode: str = "position",
        bitrate: int | None = None,
        port: int | None = None,
        bind: str | None = None,
        timeout: float = DEFAULT_TIMEOUT_S,
        counts_per_rev: int | None = None,
        encoder: str = "auto",
        fault_reset: bool = False,
        watchdog: float = DEFAULT_WATCHDOG_S,
        host_node: int = DEFAULT_HOST_NODE,
        readings: str = readings_side.OUTPUT,
        limits: Limits | None = None,
    ) -> None:
        super().__init__(
            interface=interface, channel=channel, node=node, mode=mode, bitrate=bitrate, port=port,
            bind=bind, timeout=timeout, readings=readings, limits=limits,
        )  # fmt: skip
        if not 1 <= self.node <= 127:
            raise ConfigError(f"node (={self.node}) must be 1..127 for a CANopen drive")
        self.counts_per_rev = (
            None if counts_per_rev is None else validation.integer("counts_per_rev", counts_per_rev, minimum=1)
        )
        if encoder not in ENCODERS:
            raise ConfigError(f"encoder (={encoder!r}) must be one of {', '.join(ENCODERS)}")
        self.encoder = encoder
        self.fault_reset = bool(fault_reset)
        try:
            self.watchdog_s = _watchdog(str(watchdog)) or None
            self.host_node = _node(str(host_node))
        except ValueError as exc:
            raise ConfigError(f"watchdog (={watchdog!r}) or host_node (={host_node!r}) is invalid: {exc}") from None
        if self.watchdog_s is not None and self.host_node == self.node:
            raise ConfigError(f"host_node (={self.host_node}) must differ from the drive's node (={self.node})")
        self._heartbeat: Any = None  # python-can's cyclic sender of the host's heartbeat
        self.command_step = 1.0  # targets are whole increments, or whole per mille of the rated torque
        if self.counts_per_rev is not None:
            self._set_units((self.counts_per_rev, 1), rated_torque_mnm=None)
        self._network: Any = None
        self._node: Any = None
        self._cw: Any = None
        self._target: Any = None
        self._rpdo: Any = None
        self._reply = threading.Condition()
        self._replies = 0  # TPDOs received
        self._cycles = 0  # SYNCs sent
        self._statusword = 0
        self._position = 0
        self._emcy: deque[Any] = deque()  # appended by canopen's thread, taken by ours
        self._info: dict[str, Any] = {}
        self._counter_overflow: int | None = None  # 0x1019 as configured (None: plain SYNCs)
        self._counter = 0  # the last SYNC's counter
        self._last_slot: int | None = None  # the session's slot of the last exchange
        self._restarted = False  # set by canopen's thread on a boot-up message
        self._position_object = (0x6064, 0)  # what TPDO1 carries as the position

    # ---- units -----------------------------------------------------------------------------
    def _set_units(
        self,
        main: tuple[int, int],
        *,
        rated_torque_mnm: int | None,
        gear: tuple[int, int] = (1, 1),
        read: tuple[int, int] | None = None,
    ) -> None:
        """Units from (increments, motor revolutions) of the main encoder and of the one read, and the gear."""

        def rad_per_increment(resolution: tuple[int, int]) -> float:
            increments, revolutions = resolution
            return 2 * math.pi * revolutions * gear[1] / (increments * gear[0])

        loop = UnitConversion("rad", scale=rad_per_increment(main))
        self.position_unit = loop if read is None else UnitConversion("rad", scale=rad_per_increment(read))
        if self.mode == "torque" and rated_torque_mnm is not None:
            # target torque is in per mille of the rated torque: 1 unit = rated/1000 mNm
            self.command_unit = UnitConversion("Nm", scale=rated_torque_mnm / 1e6)
        elif self.mode == "position":
            self.command_unit = loop

    # ---- primitives ------------------------------------------------------------------------
    def _open(self) -> None:
        canopen = import_vendor("canopen")
        self._replies, self._cycles, self._statusword, self._position = 0, 0, 0, 0
        self._emcy.clear()
        self._restarted, self._counter, self._last_slot = False, 0, None
        network = canopen.Network(self.address.open())
        network.NOTIFIER_CYCLE = 0.05  # so that closing does not wait a second for the reader thread
        node = canopen.RemoteNode(self.node, profile.object_dictionary(self.node))
        node.sdo.RESPONSE_TIMEOUT = max(self.timeout, 0.3)
        network.add_node(node)
        node.nmt.add_heartbeat_callback(self._on_nmt_state)
        network.connect()
        self._network, self._node = network, node
        try:
            self._configure(canopen)
        except BaseException:
            self._network, self._node = None, None
            network.disconnect()
            raise

    def _configure(self, canopen: Any) -> None:
        node = self._node
        device_type = self._sdo_read(0x1000, what="the device type")
        if device_type & 0xFFFF != 402:
            raise ProtocolError(
                f"{self._who()} is not a CiA 402 drive: device type 0x{device_type:08X}, "
                "expected profile 402 (0x0192) in the low 16 bits"
            )
        mode_code = profile.MODES[self.mode]
        supported = self._sdo_read(0x6502, what="the supported drive modes")
        if not supported & profile.SUPPORTED_MODE_BITS[mode_code]:
            raise ConfigError(
                f"{self._who()} does not support cyclic synchronous {self.mode} mode "
                f"(supported drive modes 0x6502 = 0x{supported:08X})"
            )
        node.nmt.send_command(_NMT_PRE_OPERATIONAL)
        if profile.state_of(self._sdo_read(0x6041, what="the statusword")) in _POWERED:
            # left enabled by an earlier session: torque off first
            self._sdo_call(lambda: setattr(node.sdo[0x6040], "raw", _DISABLE_VOLTAGE), "switch it off (0x6040)")
        self._sdo_call(
            lambda: setattr(node.sdo[0x6060], "raw", mode_code), f"set mode of operation {mode_code} (0x6060)"
        )
        shown = self._sdo_read(0x6061, what="the mode of operation display")
        if shown != mode_code:
            raise DeviceFault(f"{self._who()} did not take mode of operation {mode_code}: 0x6061 shows {shown}")
        main: tuple[int, int]
        if self.counts_per_rev is None:
            main = self._resolution(
                (0x608F, 1), (0x608F, 2), "the encoder resolution",
                "does not report its encoder resolution (0x608F): give counts_per_rev=<increments per revolution> in the URL",
            )  # fmt: skip
        else:
            main = (self.counts_per_rev, 1)
        gear = (
            self._sdo_read(0x6091, 1, what="the gear ratio", optional=True) or 1,
            self._sdo_read(0x6091, 2, what="the gear ratio", optional=True) or 1,
        )
        read = self._additional_resolution()
        rated = None
        if self.mode == "torque":
            rated = self._sdo_read(0x6076, what="the motor rated torque", optional=True)
            if not rated:
                raise ConfigError(f"{self._who()} reports no motor rated torque (0x6076): torque mode cannot scale Nm")
        self._set_units(main, rated_torque_mnm=rated, gear=gear, read=read)
        self._position_object = (0x6064, 0) if read is None else (0x60E4, 1)
        self._sdo_call(lambda: self._map_pdos(0x607A if self.mode == "position" else 0x6071), "map the PDOs")
        self._counter_overflow = self._sdo_write_optional(0x1019, profile.SYNC_COUNTER_OVERFLOW)
        self._start_heartbeat()
        node.emcy.add_callback(self._on_emcy)
        self._info = self._read_identity(round(main[0] / main[1]), rated)
        self._info.update(
            encoder="additional position actual value 1 (0x60E4 sub 1)" if read else "position actual value (0x6064)",
            gear_ratio=gear[0] / gear[1],
        )
        node.nmt.send_command(_NMT_OPERATIONAL)

    def _additional_resolution(self) -> tuple[int, int] | None:
        """(increments, motor revolutions) of the second encoder if it is the one to read, else None."""
        if self.encoder == "main":
            return None
        count = self._sdo_read(0x60E4, 0, what="the number of additional encoders", optional=True)
        if not count:
            if self.encoder == "additional":
                raise ConfigError(
                    f"{self._who()} has no additional position actual value (0x60E4): "
                    "read its position actual value with encoder=main"
                )
            return None
        return self._resolution(
            (0x60E6, 1), (0x60EB, 1), "the additional encoder's resolution",
            "reports an additional encoder (0x60E4) but not its resolution (0x60E6 sub 1): "
            "read its position actual value with encoder=main",
        )  # fmt: skip

    def _resolution(
        self, increments: tuple[int, int], revolutions: tuple[int, int], what: str, missing: str
    ) -> tuple[int, int]:
        """(increments, motor revolutions) from the objects at ``increments`` and ``revolutions`` (index, sub)."""
        count = self._sdo_read(*increments, what=what, optional=True)
        if not count:
            raise ConfigError(f"{self._who()} {missing}")
        return int(count), int(self._sdo_read(*revolutions, what=what, optional=True) or 1)

    def _map_pdos(self, target_index: int) -> None:
        node = self._node
        for n in range(1, 5):
            for maps in (node.rpdo, node.tpdo):
                pdo = maps[n]
                pdo.clear()
                pdo.cob_id = pdo.predefined_cob_id
                pdo.trans_type = 1  # synchronous: applied / sent on every SYNC
                pdo.enabled = n == 1
        node.rpdo[1].add_variable(0x6040)
        node.rpdo[1].add_variable(target_index)
        node.tpdo[1].add_variable(0x6041)
        node.tpdo[1].add_variable(*self._position_object)
        node.tpdo[1].add_callback(self._on_tpdo)
        for maps in (node.rpdo, node.tpdo):
            for n in range(1, 5):
                maps[n].save()
        self._rpdo = node.rpdo[1]
        self._cw, self._target = self._rpdo[0x6040], self._rpdo[target_index]

    def _start_heartbeat(self) -> None:
        """Start sending the host's heartbeat, and check the drive can watch it (0x1016, 0x6007 disable voltage).

        The drive watches it from each torque-on to the next torque-off
        (:meth:`_watch_host`): while the torque is off there is nothing to
        switch off, and a host busy compiling or plotting then may fall silent.
        """
        if self.watchdog_s is None:
            return
        if self._sdo_write_optional(0x1016, 0, subindex=1) is None:
            log.warning("%s has no heartbeat consumer (0x1016): it will not switch off if the host dies", self._who())
            self.watchdog_s = None
            return
        self._sdo_write_optional(0x6007, 2)  # disable voltage: off, and no fault to reset before the next run
        period = max(self.watchdog_s / 4, 0.01)
        self._heartbeat = self._network.send_periodic(0x700 + self.host_node, bytes([0x05]), period)  # OPERATIONAL

    def _watch_host(self, watching: bool) -> None:
        """Arm (or disarm) the drive's heartbeat consumer on the host's node."""
        if self._heartbeat is None or self.watchdog_s is None:
            return
        value = profile.heartbeat_consumer(self.host_node, round(self.watchdog_s * 1000)) if watching else 0
        self._sdo_call(lambda: setattr(self._node.sdo[0x1016][1], "raw", value), "set its heartbeat consumer (0x1016)")

    def _close(self) -> None:
        network, self._network = self._network, None
        if network is None:
            return
        try:
            if self._heartbeat is not None:
                try:
                    self._node.sdo[0x1016][1].raw = 0  # an orderly goodbye is no lost heartbeat
                except Exception as exc:  # noqa: BLE001 - the drive may be gone; its watchdog then acts
                    log.info("%s: could not switch the heartbeat consumer off: %s", self._who(), exc)
                self._heartbeat.stop()
                self._heartbeat = None
            self._node.nmt.send_command(_NMT_PRE_OPERATIONAL)  # stop the PDOs
        finally:
            network.disconnect()

    def _set_period(self, period_s: float) -> None:
        # the SYNC interval, for a drive that watches it (optional: the counter carries the slots)
        self._sdo_write_optional(0x1006, max(1, round(period_s * 1e6)))
        self._last_slot = None

    def _set_torque(self, enabled: bool) -> None:
        self._last_slot = None  # the drive's count of cycles starts afresh
        if enabled:
            self._watch_host(True)  # from now on, a host that falls silent leaves the drive switched off
            self._enable()
            return
        if self._restarted:
            return  # a drive that reset has its power stage off, and answers no SYNC before it is set up again
        statusword, _ = self._cycle(_DISABLE_VOLTAGE, self._hold_target())
        state = profile.state_of(statusword)
        if state in _POWERED:
            raise DeviceFault(f"{self._who()} did not switch off: still {state} (statusword 0x{statusword:04X})")
        self._watch_host(False)

    def _enable(self) -> None:
        self._emcy.clear()
        statusword, _ = self._cycle(_TOWARDS_ENABLED["SWITCH ON DISABLED"], self._hold_target())
        deadline_cycles = max(20, int(1.0 / self.timeout))
        reset_sent = False
        for _ in range(deadline_cycles):
            self._raise_emcy()
            state = profile.state_of(statusword)
            if state == _OE:
                return
            if state == "FAULT":
                if not self.fault_reset:
                    raise DeviceFault(
                        f"{self._who()} is in FAULT{self._error_code_text()}: clear the cause, then reset it "
                        "(add fault_reset=1 to the URL to reset it on enable)"
                    )
                if reset_sent:
                    raise DeviceFault(f"{self._who()} stays in FAULT after a fault reset{self._error_code_text()}")
                self._cycle(_DISABLE_VOLTAGE, self._hold_target())
                controlword, reset_sent = profile.CW_FAULT_RESET, True
            else:
                controlword = _TOWARDS_ENABLED.get(state, _DISABLE_VOLTAGE)
            statusword, _ = self._cycle(controlword, self._hold_target())
        raise DeviceFault(
            f"{self._who()} did not reach Operation Enabled in {deadline_cycles} cycles: "
            f"stuck in {profile.state_of(statusword)} (statusword 0x{statusword:04X})"
        )

    def _exchange(self, command: float, slot: int | None) -> Reading:
        self._raise_emcy()
        periods = 1
        if slot is not None:
            if self._last_slot is not None:
                periods = slot - self._last_slot
                if periods < 1:
                    raise DriverError(f"{self.describe()}: slot {slot} does not follow slot {self._last_slot}")
            self._last_slot = slot
        statusword, position = self._cycle(_ENABLE_OPERATION, command, periods=periods)
        self._raise_emcy()
        state = profile.state_of(statusword)
        if state != _OE:
            raise DeviceFault(
                f"{self._who()} left Operation Enabled: statusword 0x{statusword:04X} = {state}"
                f"{self._error_code_text() if state == 'FAULT' else ''}"
            )
        return Reading(position=float(position))

    def _read(self) -> Reading:
        index, subindex = self._position_object
        return Reading(position=float(self._sdo_read(index, subindex or None, what="the actual position")))

    def _identity(self) -> dict[str, Any]:
        return dict(self._info)

    # ---- the cycle -------------------------------------------------------------------------
    def _cycle(self, controlword: int, target: float, *, periods: int = 1) -> tuple[int, int]:
        """RPDO1 (controlword, target) then SYNC; wait for TPDO1; return (statusword, position).

        ``periods``: cycles since the previous SYNC, which the SYNC counter advances by.
        """
        self._raise_restart()
        low, high = _INT32 if self.mode == "position" else _INT16
        value = round(target)
        if not low <= value <= high:
            raise ConfigError(
                f"target (={value} drive units) is outside the drive's range {low}..{high}; "
                "set min/max in the URL to keep commands in range"
            )
        self._cw.raw = controlword
        self._target.raw = value
        with self._reply:
            if self._replies < self._cycles:
                # the last cycle timed out: let its TPDO arrive now rather than answer this one
                self._reply.wait_for(lambda: self._replies >= self._cycles, self.timeout)
            before = self._replies
            self._cycles = before + 1
        self._rpdo.transmit()
        if self._counter_overflow:
            self._counter = (self._counter + periods - 1) % self._counter_overflow + 1
            self._network.sync.transmit(self._counter)
        else:
            self._network.sync.transmit()
        with self._reply:
            answered = self._reply.wait_for(lambda: self._replies > before or self._restarted, self.timeout)
            self._raise_restart()
            if not answered:
                raise DriverTimeout(
                    f"{self._who()}: no TPDO within {self.timeout * 1e3:.0f} ms after SYNC (the drive stopped answering)"
                )
            return self._statusword, self._position

    def _hold_target(self) -> float:
        """The target that keeps the drive where it is: the actual position, or zero torque."""
        if self.mode == "torque":
            return 0.0
        if self._replies and self._position_object == (0x6064, 0):
            return float(self._position)
        # the target counts the loop's encoder; the position read may be another's
        return float(self._sdo_read(0x6064, what="the actual position"))

    # ---- callbacks (canopen's notifier thread) --------------------------------------------------
    def _on_tpdo(self, pdo: Any) -> None:
        statusword, position = int(pdo.map[0].raw), int(pdo.map[1].raw)  # as mapped: statusword, position
        with self._reply:
            self._statusword, self._position = statusword, position
            self._replies += 1
            self._reply.notify_all()

    def _on_nmt_state(self, state: int) -> None:
        if state == 0:  # a boot-up message: the drive reset
            with self._reply:
                self._restarted = True
                self._reply.notify_all()

    def _on_emcy(self, error: Any) -> None:
        if error.code & 0xFF00:  # 0x00xx is "error reset / no error"
            self._emcy.append(error)

    # ---- helpers -------------------------------------------------------------------------------
    def _raise_restart(self) -> None:
        if self._restarted:
            raise DeviceRestarted(
                f"{self._who()} restarted (it sent a boot-up message): its power stage is off and the "
                "configuration servoid gave it (PDO mapping, mode of operation) is lost; open it again"
            )

    def _raise_emcy(self) -> None:
        errors = []
        while self._emcy:
            errors.append(self._emcy.popleft())
        if not errors:
            return
        first = errors[0]
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise DeviceFault(
            f"{self._who()} reported {profile.emcy_text(first.code, first.register)}{more}; "
            f"state {profile.state_of(self._statusword)}"
        )

    def _error_code_text(self) -> str:
        try:
            code = self._sdo_read(0x603F, what="the error code", optional=True)
        except DriverTimeout:
            return ""
        return f" (error code 0x603F = 0x{code:04X}: {profile.emcy_text(code)})" if code else ""

    def _sdo_call(self, action: Callable[[], Any], what: str) -> Any:
        """SDO downloads (``action``) with canopen's errors said in the drive's terms."""
        canopen = import_vendor("canopen")
        try:
            return action()
        except canopen.SdoCommunicationError as exc:
            raise DriverTimeout(f"{self._who()} stopped answering SDO requests while trying to {what}") from exc
        except canopen.SdoAbortedError as exc:
            raise ProtocolError(f"{self._who()} refused to {what}: {exc}") from exc

    def _sdo_write_optional(self, index: int, value: int, *, subindex: int | None = None) -> int | None:
        """Write an object the drive may not have; ``value`` if it took it, None if it refused."""
        canopen = import_vendor("canopen")
        try:
            entry = self._node.sdo[index] if subindex is None else self._node.sdo[index][subindex]
            entry.raw = value
        except canopen.SdoCommunicationError as exc:
            raise DriverTimeout(f"{self._who()} stopped answering SDO requests (writing 0x{index:04X})") from exc
        except (canopen.SdoAbortedError, KeyError):
            return None
        return value

    def _sdo_read(self, index: int, subindex: int | None = None, *, what: str, optional: bool = False) -> Any:
        """One SDO upload; no answer is DriverTimeout, an abort raises unless ``optional`` (then None)."""
        canopen = import_vendor("canopen")
        entry = self._node.sdo[index] if subindex is None else self._node.sdo[index][subindex]
        try:
            return entry.raw
        except canopen.SdoCommunicationError as exc:
            raise DriverTimeout(
                f"{self._who()} does not answer (no SDO reply reading {what}, 0x{index:04X}, "
                f"in {self._node.sdo.RESPONSE_TIMEOUT:g} s): is it powered, is node={self.node} right, "
                "is the bit rate right?"
            ) from exc
        except canopen.SdoAbortedError as exc:
            if optional:
                return None
            raise ProtocolError(f"{self._who()} refused to give {what} (0x{index:04X}): {exc}") from exc

    def _read_identity(self, counts_per_rev: int, rated_torque_mnm: int | None) -> dict[str, Any]:
        info: dict[str, Any] = {
            "driver": "can",
            "protocol": "CiA 402",
            "node": self.node,
            "mode": self.mode,
            "counts_per_rev": counts_per_rev,
        }
        if rated_torque_mnm is not None:
            info["rated_torque_mNm"] = rated_torque_mnm
        names = {
            "device_name": (0x1008, None), "hardware_version": (0x1009, None), "software_version": (0x100A, None),
            "vendor_id": (0x1018, 1), "product_code": (0x1018, 2), "revision": (0x1018, 3), "serial_number": (0x1018, 4),
        }  # fmt: skip
        for key, (index, sub) in names.items():
            value = self._sdo_read(index, sub, what=key.replace("_", " "), optional=True)
            if value not in (None, ""):
                info[key] = value
        return info
