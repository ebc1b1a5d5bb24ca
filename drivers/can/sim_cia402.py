"""A simulated CiA 402 servo drive: a canopen LocalNode with a twin (or the bench plant) behind it.

The drive is what a CANopen master meets on a real bus: an SDO server on its
object dictionary (:mod:`servoid.drivers.can.cia402_od`), NMT slave, boot-up
message, EMCY producer, PDOs mapped by the master through SDO, and the CiA
402 state machine driven by the controlword (0x6040) and shown in the
statusword (0x6041), in cyclic synchronous position (8) or torque (10) mode.

Cycle (see :mod:`servoid.drivers.can._sim_axis`): the RPDOs the master
sends are latched, and on each SYNC the drive applies the latched
controlword, runs its control cycle with the latched target (only in
Operation Enabled: one sample of the plant, after the held samples of any
cycles whose SYNC never came, which the SYNC counter shows), and answers
with its TPDOs (statusword, actual position). Positions are in encoder
increments; torques in per mille of the rated torque (0x6071, 0x6076).

The servo (:mod:`servoid.drivers.servos`, default the ``cia402`` twin: an
EPOS4-class drive, its loop on a motor encoder, a load encoder behind a
planetary gear) is reported as such a drive reports it: 0x6064 (position
actual value) and 0x607A (target position) in increments of the encoder the
position loop closes on, 0x608F their resolution per motor revolutions,
0x6091 the gear ratio, and the other encoder -- the load encoder, on the
output -- in 0x60E4 sub 1 (additional position actual value, resolution in
0x60E6 / 0x60EB). With the pseudo-Wiener plant (``servo="model"``) the drive
has one encoder of ``counts_per_rev`` increments on the output and no gear.
Torque mode drives a twin's current loop on the target torque (motor torque,
per mille of 0x6076); a twin without one (the Dynamixel's or Feetech's
firmware behind this drive) offers cyclic synchronous position only (0x6502).

SYNC counter (CiA 301): with a synchronous counter overflow value (0x1019,
2..240) configured, each SYNC carries a counter 1..overflow; the difference
to the previous SYNC's counter is the number of cycles that passed. The
communication cycle period (0x1006, us) resolves a gap longer than the
counter's range; a SYNC without a counter is one cycle.

Faults for tests: :meth:`SimCia402Drive.inject_fault` (FAULT with an EMCY),
:meth:`SimCia402Drive.drop_out` (leaves Operation Enabled without an EMCY,
like a lost enable input), each applied at the next SYNC so that tests are
deterministic; :meth:`SimCia402Drive.mute` and ``mute_after`` (the drive
keeps listening and obeying, but sends nothing: a broken transmitter),
``drop`` (a lost TPDO now and then), ``restart_after`` (the drive resets at
a SYNC: boot-up message, PRE-OPERATIONAL, configuration lost, power off).

Heartbeat consumer (CiA 301, 0x1016): with a node and a time configured,
the drive watches that node's heartbeat from the first one it hears; when
none comes for the time (the master died, the cable was cut), it sends EMCY
0x8130, acts as the abort connection option code says (0x6007: 1 fault, the
default; 2 disable voltage; 3 quick stop, then disabled) and goes to NMT
PRE-OPERATIONAL (0x1029's default). ``on_event`` hears it, and every time the
power stage goes off.

Not modelled: node guarding, the quick stop ramp, event-driven PDOs.

Examples
--------
>>> with SimCia402Drive(node=1, bus=BusAddress("virtual", "bench")) as drive:   # doctest: +SKIP
...     with driver_from_url(drive.url()) as servo:
...         servo.enable()
...         servo.exchange(0.1)
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any

from servoid import validation
from servoid.drivers.can import cia402_od as profile
from servoid.drivers.can._bus import BusAddress, import_vendor
from servoid.drivers.can._sim_axis import TORQUE_GAIN
from servoid.drivers.can._sim_base import SimDrive
from servoid.drivers.can._sim_facts import SIM_COUNTS_PER_REV, SIM_RATED_TORQUE_MNM
from servoid.drivers.can.driver import DEFAULT_NODES
from servoid.drivers.servos import Servo, parse_servo
from servoid.errors import ConfigError

__all__ = ["SimCia402Drive", "SIM_COUNTS_PER_REV", "SIM_RATED_TORQUE_MNM"]

log = logging.getLogger("servoid.drivers.can.sim")

#: EMCY code of a twin that turned its output off on overspeed (CiA 301/402: speed controller).
_EMCY_SPEED = 0x8400

_OE = "OPERATION ENABLED"
_QSA = "QUICK STOP ACTIVE"
_SOD = "SWITCH ON DISABLED"
_POWERED = (_OE, _QSA)
_VOLTAGE = ("READY TO SWITCH ON", "SWITCHED ON", _OE, _QSA)
_MODES = tuple(profile.MODES.values())  # the modes of operation the drive accepts: CSP, CST
_REMOTE = 0x0200  # statusword bit 9: the drive follows the controlword
_VOLTAGE_ENABLED = 0x0010  # statusword bit 4
_CSP_FOLLOWING = 0x1000  # statusword bit 12 in CSP/CST: the target is followed


def _next_state(state: str, controlword: int) -> str:
    """CiA 402 device control (transitions 2-12 and 16) for one controlword."""
    disable_voltage = controlword & 0x82 == 0x00
    quick_stop = controlword & 0x86 == 0x02
    shutdown = controlword & 0x87 == 0x06
    switch_on = controlword & 0x8F == 0x07
    enable = controlword & 0x8F == 0x0F
    if state == _SOD:
        return "READY TO SWITCH ON" if shutdown else state  # 2
    if state == "READY TO SWITCH ON":
        if disable_voltage or quick_stop:
            return _SOD  # 7
        if switch_on:
            return "SWITCHED ON"  # 3
        return _OE if enable else state  # 3 + 4, as most drives do
    if state == "SWITCHED ON":
        if disable_voltage or quick_stop:
            return _SOD  # 10
        if shutdown:
            return "READY TO SWITCH ON"  # 6
        return _OE if enable else state  # 4
    if state == _OE:
        if disable_voltage:
            return _SOD  # 9
        if quick_stop:
            return _QSA  # 11
        if shutdown:
            return "READY TO SWITCH ON"  # 8
        return "SWITCHED ON" if switch_on else state  # 5
    if state == _QSA:
        if disable_voltage:
            return _SOD  # 12
        return _OE if enable else state  # 16
    return state


class SimCia402Drive(SimDrive):
    """A simulated CiA 402 drive on a python-can bus (see the module docstring).

    Parameters
    ----------
    node : int
        CANopen node id, 1..127.
    bus, torque_gain
        As for :class:`~servoid.drivers.can._sim_base.SimDrive`.
    servo : Servo or str
        The servo behind the drive (default the ``cia402`` twin; text as
        :func:`~servoid.drivers.servos.parse_servo` reads it: ``"model"``,
        ``"cia402?play_arcmin=3"``).
    counts_per_rev : int, optional
        With the pseudo-Wiener plant: encoder increments per revolution,
        reported in 0x608F (default :data:`SIM_COUNTS_PER_REV`). A twin's
        encoders are its own (``motor_encoder_cpr``, ``load_encoder_cpr``).
    rated_torque_mnm : int
        Motor rated torque (0x6076), mNm.
    device_type : int
        What 0x1000 says (default a CiA 402 servo drive; tests set others).
    mute_after, drop, restart_after, seed
        Injected faults (:class:`~servoid.drivers.can._sim_base.SimDrive`),
        counted in SYNCs answered in Operation Enabled.
    """

    protocol = "cia402"

    def __init__(
        self,
        *,
        node: int = DEFAULT_NODES["cia402"],
        bus: BusAddress | None = None,
        servo: Servo | str = "cia402",
        counts_per_rev: int | None = None,
        rated_torque_mnm: int = SIM_RATED_TORQUE_MNM,
        torque_gain: float = TORQUE_GAIN,
        device_type: int = profile.DEVICE_TYPE_402,
        mute_after: int | None = None,
        drop: float = 0.0,
        restart_after: int | None = None,
        seed: int = 0,
    ) -> None:
        node = validation.integer("node", node, minimum=1)
        if node > 127:
            raise ConfigError(f"node (={node}) must be 1..127 for a CANopen drive")
        servo = servo if isinstance(servo, Servo) else parse_servo(servo)
        super().__init__(
            node=node, bus=bus, servo=servo, torque_gain=torque_gain, mute_after=mute_after, drop=drop,
            restart_after=restart_after, seed=seed,
        )  # fmt: skip
        self.encoders = _Encoders.of(servo, counts_per_rev)
        self.rated_torque_mnm = validation.integer("rated_torque_mnm", rated_torque_mnm, minimum=1)
        self.device_type = validation.integer("device_type", device_type, minimum=0)
        self._state = _SOD
        self.counter_overflow = 0  # 0x1019: 0, no SYNC counter
        self.restarts = 0
        self.mode = 0
        self.error_code = 0
        self.syncs = 0
        self._controlword = 0
        self._pending: list[tuple[str, Any]] = []
        self._lock = threading.RLock()
        self._network: Any = None
        self._node: Any = None
        self._rx: dict[int, Any] = {}
        self._tx_maps: list[Any] = []
        self._subscribed: list[tuple[int, Any]] = []
        self.abort_option = 1  # 0x6007
        self._consumer: tuple[int, float] | None = None  # (node, seconds) of 0x1016 sub 1
        self._heard: float | None = None  # monotonic time of the watched node's last heartbeat
        self._watch: threading.Thread | None = None
        self._watching = threading.Event()

    # ---- life cycle ----------------------------------------------------------------------
    def start(self) -> SimCia402Drive:
        """Connect to the bus and boot (boot-up message, then PRE-OPERATIONAL)."""
        if self._network is not None:
            return self
        canopen = import_vendor("canopen")
        enc = self.encoders
        dictionary = profile.object_dictionary(self.node, additional=enc.additional is not None)
        dictionary[0x1000].default = self.device_type
        dictionary[0x1008].default = "servoid simulated CiA 402 drive"
        dictionary[0x1009].default = "sim"
        dictionary[0x100A].default = "servoid"
        dictionary[0x1018][2].default = 0x0402
        dictionary[0x1018][4].default = self.node
        dictionary[0x6076].default = self.rated_torque_mnm
        dictionary[0x608F][1].default, dictionary[0x608F][2].default = enc.main
        dictionary[0x6091][1].default, dictionary[0x6091][2].default = enc.gear
        if enc.additional is not None:
            dictionary[0x60E6][1].default, dictionary[0x60EB][1].default = enc.additional
        if not self.axis.torque_capable:
            dictionary[0x6502].default = profile.SUPPORTED_MODE_BITS[profile.MODES["position"]]
        network = _network_class(canopen)(self.bus.open())
        network.NOTIFIER_CYCLE = 0.05  # so that stop() does not wait a second for the reader thread
        network.drive = self
        node = canopen.LocalNode(self.node, dictionary)
        node.add_read_callback(self._on_read)
        node.add_write_callback(self._on_write)
        network.add_node(node)
        network.subscribe(0x80, self._on_sync)
        network.subscribe(0, self._on_nmt)  # after the node's own NMT slave has seen the command
        self._network, self._node = network, node
        network.connect()
        node.nmt.send_command(0x81)  # reset: boot-up message
        node.nmt.send_command(0x80)  # pre-operational
        self._watching.set()
        self._watch = threading.Thread(target=self._watch_heartbeat, name=f"sim-cia402-{self.node}-hb", daemon=True)
        self._watch.start()
        return self

    def stop(self) -> None:
        """Leave the bus; idempotent."""
        network, self._network = self._network, None
        self._watching.clear()
        if self._watch is not None:
            self._watch.join(timeout=2.0)
            self._watch = None
        if network is not None:
            network.disconnect()

    # ---- what tests look at ----------------------------------------------------------------
    @property
    def state(self) -> str:
        """The CiA 402 state (``"OPERATION ENABLED"``, ...)."""
        return self._state

    @state.setter
    def state(self, state: str) -> None:
        was_powered = self._state in _POWERED
        self._state = state
        self.axis.power(state == _OE)  # the plant follows targets in Operation Enabled only
        if was_powered and state not in _POWERED:
            self._event(f"power stage off ({state})")

    @property
    def power_on(self) -> bool:
        """Whether the power stage is on (Operation Enabled or Quick Stop Active)."""
        return self.state in _POWERED

    @property
    def nmt_state(self) -> str:
        return str(self._node.nmt.state) if self._node is not None else "STOPPED"

    @property
    def statusword(self) -> int:
        sw = profile.statusword_of(self.state) | _REMOTE
        if self.state in _VOLTAGE:
            sw |= _VOLTAGE_ENABLED
        if self.state == _OE:
            sw |= _CSP_FOLLOWING
        return sw

    @property
    def position_counts(self) -> int:
        """Position actual value (0x6064): increments of the encoder the position loop closes on."""
        reading = self.axis.reading
        if reading is None:
            return round(self.axis.position / (2 * math.pi) * self.encoders.main[0])
        loop = self.axis.servo.twin.loop_encoder  # type: ignore[union-attr]
        return _counts(reading.motor_counts if loop == "motor" else reading.load_counts)

    @property
    def additional_counts(self) -> int:
        """Additional position actual value 1 (0x60E4 sub 1): the other encoder's increments (0 without one)."""
        reading = self.axis.reading
        if reading is None or self.encoders.additional is None:
            return 0
        loop = self.axis.servo.twin.loop_encoder  # type: ignore[union-attr]
        return _counts(reading.load_counts if loop == "motor" else reading.motor_counts)

    def status(self) -> str:
        """One line for a terminal."""
        return (
            f"node {self.node}: NMT {self.nmt_state}, {self.state}, mode {self.mode}, "
            f"{self.syncs} SYNCs, position {self.axis.position:+.4f} rad"
        )

    # ---- fault injection (applied at the next SYNC) -------------------------------------------
    def inject_fault(self, code: int = 0x2310, register: int = 0x03) -> None:
        """Fault at the next SYNC: FAULT state, power off, EMCY ``code`` (default 0x2310, over-current)."""
        with self._lock:
            self._pending.append(("fault", (code, register)))

    def drop_out(self, state: str = _SOD) -> None:
        """Leave Operation Enabled at the next SYNC without an EMCY (a lost enable input)."""
        with self._lock:
            self._pending.append(("drop", state))

    # ---- bus callbacks (the canopen notifier thread) ------------------------------------------
    def _on_read(self, *, index: int, subindex: int, od: Any) -> Any:  # noqa: ARG002 - canopen's signature
        if index == 0x60E4:
            return self.additional_counts if subindex == 1 else None
        live = {
            0x1001: 0x01 if self.state == "FAULT" else 0,
            0x603F: self.error_code,
            0x6041: self.statusword,
            0x6061: self.mode,
            0x6064: self.position_counts,
            0x6077: 0,
        }
        return live.get(index)

    def _on_write(self, *, index: int, subindex: int, od: Any, data: bytes) -> None:  # noqa: ARG002
        canopen = import_vendor("canopen")
        value = od.decode_raw(data)
        with self._lock:
            if index == 0x6060:
                if value not in _MODES or (value == profile.MODES["torque"] and not self.axis.torque_capable):
                    raise canopen.SdoAbortedError(0x06090030)  # value range of parameter exceeded
                self.mode = int(value)
            elif index == 0x6040:
                self._apply_controlword(int(value))
            elif index == 0x6076:
                self.rated_torque_mnm = max(int(value), 1)
            elif index == 0x1006:
                self.axis.set_period(value * 1e-6 if value else None)
            elif index == 0x1019:
                if value == 1 or value > 240:
                    raise canopen.SdoAbortedError(0x06090030)
                self.counter_overflow = int(value)
                self.axis.set_counter(self.counter_overflow or None)
            elif index == 0x1016 and subindex == 1:
                self._watch_node(int(value))
            elif index == 0x6007:
                if value not in profile.ABORT_OPTIONS:
                    raise canopen.SdoAbortedError(0x06090030)
                self.abort_option = int(value)

    def _on_nmt(self, can_id: int, data: bytes, timestamp: float) -> None:  # noqa: ARG002
        with self._lock:
            if self.nmt_state == "OPERATIONAL":
                self._read_pdo_configuration()
            elif self.power_on:
                # the master left OPERATIONAL with the drive enabled: disable (0x6007 option "disable voltage")
                log.info("node %d: NMT left OPERATIONAL while enabled, disabling", self.node)
                self.state = _SOD

    def _on_sync(self, can_id: int, data: bytes, timestamp: float) -> None:  # noqa: ARG002 - timestamp: the bus's
        with self._lock:
            self.syncs += 1
            if self.nmt_state == "OPERATIONAL" and 0x6040 in self._rx:
                self._apply_controlword(int(self._rx[0x6040].raw))
            self._apply_pending()  # after the master's command, so that the injected state is what it sees
            if self.nmt_state != "OPERATIONAL":
                return
            if self.state == _OE and self.mode in _MODES:
                if self._restart_due():
                    self._restart()
                    return
                counter = data[0] if data and self.counter_overflow else None
                torque = self.mode == profile.MODES["torque"]
                self.axis.step(self._target(), torque=torque, at=timestamp or time.time(), slot=counter)
                twin = self.axis.twin
                if twin is not None and twin.twin.read().fault is not None:
                    # the twin turned its output off by itself (an overspeed): FAULT, with an EMCY
                    self.state, self.error_code = "FAULT", _EMCY_SPEED
                    self._node.emcy.send(_EMCY_SPEED, 0x01)
                if self._reply_lost():
                    return
            for pdo in self._tx_maps:
                if self.syncs % max(pdo.trans_type, 1) == 0:
                    for var in pdo:
                        var.set_data(self._node.get_data(var.index, var.subindex))
                    pdo.transmit()

    # ---- the heartbeat consumer -----------------------------------------------------------------
    def _watch_node(self, value: int) -> None:
        """0x1016 sub 1 written: watch node ``value >> 16 & 0x7F`` for ``value & 0xFFFF`` ms (0: nothing)."""
        if self._consumer is not None:
            self._network.unsubscribe(0x700 + self._consumer[0], self._on_heartbeat)
        node, time_ms = value >> 16 & 0x7F, value & 0xFFFF
        self._consumer = (node, time_ms / 1000.0) if node and time_ms else None
        self._heard = None  # CiA 301: watching starts with the first heartbeat heard
        if self._consumer is not None:
            self._network.subscribe(0x700 + node, self._on_heartbeat)

    def _on_heartbeat(self, can_id: int, data: bytes, timestamp: float) -> None:  # noqa: ARG002
        with self._lock:
            self._heard = time.monotonic()

    def _watch_heartbeat(self) -> None:
        """The consumer's timer, a thread of its own: nothing arrives to wake the drive when the master died."""
        while self._watching.is_set():
            with self._lock:
                consumer, heard = self._consumer, self._heard
                if consumer is not None and heard is not None and time.monotonic() - heard > consumer[1]:
                    self._heartbeat_lost(consumer[0], time.monotonic() - heard)
            time.sleep(0.005)

    def _heartbeat_lost(self, node: int, silent_s: float) -> None:
        """CiA 301 heartbeat event: EMCY, the abort connection option (0x6007), NMT PRE-OPERATIONAL."""
        self._heard = None  # one event per loss; watching resumes with the next heartbeat
        action = profile.ABORT_OPTIONS.get(self.abort_option, "fault")
        if self.abort_option == 1:
            self.state, self.error_code = "FAULT", profile.EMCY_COMMUNICATION
        elif self.abort_option in (2, 3):
            self.state = _SOD
        self._node.emcy.send(profile.EMCY_COMMUNICATION, 0x11)  # generic + communication error
        self._node.nmt.state = "PRE-OPERATIONAL"
        self._event(f"heartbeat of node {node} lost (none for {silent_s * 1e3:.0f} ms): {action}, now {self.state}")

    # ---- helpers -------------------------------------------------------------------------------
    def _target(self) -> float:
        """The latched target as the plant's input: rad, or Nm in torque mode."""
        if self.mode == profile.MODES["torque"]:
            var = self._rx.get(0x6071)
            return 0.0 if var is None else var.raw / 1000.0 * self.rated_torque_mnm / 1000.0
        var = self._rx.get(0x607A)
        return self.axis.position if var is None else var.raw * self.encoders.rad_per_increment

    def _apply_controlword(self, controlword: int) -> None:
        rising_reset = controlword & profile.CW_FAULT_RESET and not self._controlword & profile.CW_FAULT_RESET
        self._controlword = controlword
        if self.state == "FAULT":
            if rising_reset:
                self.state, self.error_code = _SOD, 0  # 15
            return
        self.state = _next_state(self.state, controlword)

    def _apply_pending(self) -> None:
        for kind, arg in self._pending:
            if kind == "fault":
                code, register = arg
                self.state, self.error_code = "FAULT", code
                self._node.emcy.send(code, register)
            elif kind == "drop":
                self.state = arg
        self._pending.clear()

    def _restart(self) -> None:
        """Reset as after a power glitch: boot-up message, PRE-OPERATIONAL, power off, configuration lost."""
        log.info("node %d: restarting (injected)", self.node)
        self.restarts += 1
        self.state, self.mode, self._controlword = _SOD, 0, 0
        self.counter_overflow = 0
        self.axis.set_counter(None)
        self.axis.set_period(None)
        self._node.data_store.clear()  # what the master wrote by SDO (PDO mapping, mode, ...) is gone
        self._node.nmt.send_command(0x81)  # reset node: boot-up message
        self._node.nmt.send_command(0x80)

    def _read_pdo_configuration(self) -> None:
        """Take the PDO mapping the master wrote (over SDO) into effect, as a drive does on NMT start."""
        for cob_id, callback in self._subscribed:
            self._network.unsubscribe(cob_id, callback)
        self._subscribed.clear()
        self._node.rpdo.read()
        self._node.tpdo.read()
        self._rx = {}
        for pdo in self._node.rpdo.map.values():
            if pdo.enabled:
                self._subscribed.append((pdo.cob_id, pdo.on_message))
                self._rx.update({var.index: var for var in pdo})
        self._tx_maps = [p for p in self._node.tpdo.map.values() if p.enabled and p.trans_type and p.trans_type <= 240]
        for pdo in self._node.tpdo.map.values():
            if pdo.enabled:
                # a LocalNode's TPDO subscribes to its own COB-ID; nothing is to be received there
                self._subscribed.append((pdo.cob_id, pdo.on_message))


def _counts(value: int | None) -> int:
    return 0 if value is None else int(value)


class _Encoders:
    """The drive's encoders as CiA 402 states them (see the module docstring).

    ``main`` and ``additional`` are (increments, motor revolutions) pairs
    (0x608F; 0x60E6 / 0x60EB sub 1), ``gear`` is (motor shaft, driving shaft)
    revolutions (0x6091), ``rad_per_increment`` the output angle of one
    increment of the main encoder (target and actual position).
    """

    def __init__(self, main: tuple[int, int], gear: tuple[int, int], additional: tuple[int, int] | None) -> None:
        self.main, self.gear, self.additional = main, gear, additional
        self.rad_per_increment = 2.0 * math.pi * main[1] * gear[1] / (main[0] * gear[0])

    @classmethod
    def of(cls, servo: Servo, counts_per_rev: int | None) -> _Encoders:
        twin = servo.twin
        if twin is None:
            cpr = SIM_COUNTS_PER_REV if counts_per_rev is None else counts_per_rev
            return cls((validation.integer("counts_per_rev", cpr, minimum=1), 1), (1, 1), None)
        if counts_per_rev is not None:
            raise ConfigError(
                f"counts_per_rev (={counts_per_rev!r}) sets the encoder of the pseudo-Wiener plant (servo model); "
                f"the twin {servo.name!r} has its own: motor_encoder_cpr, load_encoder_cpr"
            )
        p, q = profile.gear_fraction(twin.gear_ratio)
        motor = (twin.motor_encoder_cpr, 1) if twin.motor_encoder_cpr else None
        load = (twin.load_encoder_cpr * q, p) if twin.load_encoder_cpr else None
        main, other = (motor, load) if twin.loop_encoder == "motor" else (load, motor)
        assert main is not None  # TwinParams checks the loop has its encoder
        return cls(main, (p, q), other)


_NETWORK_CLASS: Any = None


def _network_class(canopen: Any) -> Any:
    """A canopen Network whose transmitter the simulated drive can switch off (:meth:`mute`)."""
    global _NETWORK_CLASS
    if _NETWORK_CLASS is None:

        class _DriveNetwork(canopen.Network):  # type: ignore[misc]
            drive: SimCia402Drive | None = None

            def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
                if self.drive is not None and self.drive._muted:
                    return
                super().send_message(can_id, data, remote)

        _NETWORK_CLASS = _DriveNetwork
    return _NETWORK_CLASS
