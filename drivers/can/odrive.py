"""An ODrive axis over CAN Simple, in position or torque control (message set: ``odrive_protocol``).

Opening: a remote request for the encoder estimates proves the node answers
(no reply is :class:`~servoid.errors.DriverTimeout`), the axis is sent to
IDLE (torque stays off until asked), the controller mode is set (position or
torque control, passthrough input), and the versions are asked for (firmware
0.6; older boards stay silent, which is fine).

Each cyclic exchange sends Set_Input_Pos (or Set_Input_Torque), then a
remote request for Get_Encoder_Estimates, and reads the bus until the
estimates arrive. Heartbeats read on the way are checked: an axis error, or
an axis that left closed-loop control, is :class:`~servoid.errors.DeviceFault`
(with the axis error's names and, when the board answers Get_Error, the
active errors and the disarm reason). Torque on is Set_Axis_State
CLOSED_LOOP_CONTROL, torque off is IDLE, each confirmed by a heartbeat.

The axis watchdog (``watchdog=S``): every frame the driver sends feeds it,
and an axis left in closed-loop control by a host that died (SIGKILL, a
crash, a cut cable) disarms within S seconds. Its settings are endpoints
whose ids change with every firmware build, so the driver writes them
(RxSdo) only from the board's own ``flat_endpoints.json`` (``endpoints=PATH``,
checked against the firmware version the board reports), and reads them
back; without it, set them on the board once (odrivetool:
``odrv0.axis0.config.watchdog_timeout = 0.5``, ``enable_watchdog = True``,
``save_configuration()``). An axis that disarmed on its watchdog alone
(WATCHDOG_TIMER_EXPIRED, what the last host left) has that error cleared
when the torque is switched on again; any other error is reported.

The bus is read in the caller's thread (no background reader): frames are
handled in the order they came, so a heartbeat that announces an error is
seen before the estimates that follow it.

Units: positions in turns (native), radians for the user; torque in Nm both;
``velocity`` in the measurement is in rad/s. The protocol has no device clock
(``device_time`` is None). On a real ODrive, set ``encoder_msg_rate_ms = 0``
so that only requested estimates arrive: a cyclic estimate can otherwise
answer an exchange a little early.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping
from typing import Any, ClassVar

from servoid import readings_side, validation
from servoid.drivers.base import Limits, Option, Reading, UnitConversion
from servoid.drivers.can import odrive_protocol as proto
from servoid.drivers.can._bus import import_vendor
from servoid.drivers.can.driver import DEFAULT_NODES, DEFAULT_TIMEOUT_S, CanDriver
from servoid.errors import ConfigError, DeviceFault, DriverTimeout, ProtocolError

__all__ = ["OdriveDriver"]

_TWO_PI = 2 * math.pi

#: Longest wait for a heartbeat that confirms a state change, s (ODrive sends one every 100 ms by default).
STATE_TIMEOUT_S = 1.0


def _read_endpoints(path: str) -> tuple[str, dict[str, tuple[int, str]]]:
    """``(firmware version, {name: (id, type)})`` of the watchdog's endpoints, from a flat_endpoints.json."""
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
        endpoints = data["endpoints"]
        table = {name: (int(endpoints[name]["id"]), str(endpoints[name]["type"])) for name in proto.WATCHDOG_ENDPOINTS}
        firmware = str(data["fw_version"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(
            f"endpoints (={path!r}) must be an ODrive flat_endpoints.json with fw_version and the endpoints "
            f"{' and '.join(proto.WATCHDOG_ENDPOINTS)} ({type(exc).__name__}: {exc})"
        ) from None
    if table[proto.WATCHDOG_ENDPOINTS[0]][1] != "float" or table[proto.WATCHDOG_ENDPOINTS[1]][1] != "bool":
        raise ConfigError(
            f"endpoints (={path!r}): the watchdog's endpoints have types {table}, expected float and bool"
        )
    return firmware, table


class OdriveDriver(CanDriver):
    """An ODrive axis over CAN Simple (see the module docstring).

    Parameters
    ----------
    interface, channel, node, mode, bitrate, port, bind, timeout, limits
        As for :class:`~servoid.drivers.can.driver.CanDriver`; node 0..63
        (``odrv0.axis0.config.can.node_id``).
    watchdog : float, optional
        Axis watchdog timeout to set, s (0: switch it off); needs ``endpoints``.
        None (default) leaves the board's own setting.
    endpoints : str, optional
        Path of the board's ``flat_endpoints.json`` (its endpoint ids).
    readings : {"motor", "output"}
        Which shaft Get_Encoder_Estimates reports (:attr:`~servoid.drivers.base.Driver.readings_side`):
        the axis's own encoder, on the motor (the default, as a board is shipped), or ``"output"`` when
        a load encoder was made the axis's position source (ODrive 0.6: ``axis.config.load_encoder``).
        The board does not say which over CAN Simple; the play between motor and output is not in
        a record read on the motor, and identification says so.
    """

    protocol = "odrive"
    options: ClassVar[Mapping[str, Option]] = {
        **CanDriver.options,
        "watchdog": Option(float, "axis watchdog timeout to set, s, 0: off (needs endpoints=; default: the board's)"),
        "endpoints": Option(str, "path of the board's flat_endpoints.json, whose ids watchdog= is written with"),
    }

    def __init__(
        self,
        *,
        interface: str,
        channel: str = "",
        node: int = DEFAULT_NODES["odrive"],
        mode: str = "position",
        bitrate: int | None = None,
        port: int | None = None,
        bind: str | None = None,
        timeout: float = DEFAULT_TIMEOUT_S,
        watchdog: float | None = None,
        endpoints: str | None = None,
        readings: str = readings_side.MOTOR,
        limits: Limits | None = None,
    ) -> None:
        turns = UnitConversion("rad", scale=_TWO_PI)
        super().__init__(
            interface=interface, channel=channel, node=node, mode=mode, bitrate=bitrate, port=port,
            bind=bind, timeout=timeout, readings=readings, limits=limits, position_unit=turns,
            command_unit=turns if mode == "position" else UnitConversion("Nm", scale=1.0),
        )  # fmt: skip
        if self.node > 63:
            raise ConfigError(f"node (={self.node}) must be 0..63 for ODrive CAN Simple (11-bit ids)")
        self._bus: Any = None
        self._can: Any = None
        self._heartbeat: proto.Heartbeat | None = None
        self._beats = 0
        self._outstanding = False  # a request whose reply may still come
        self._position = 0.0
        self._info: dict[str, Any] = {}
        if watchdog is not None:
            watchdog = validation.non_negative("watchdog", watchdog)
            if endpoints is None:
                raise ConfigError(
                    f"watchdog (={watchdog:g}) needs endpoints=<the board's flat_endpoints.json>: an ODrive's endpoint "
                    "ids change with its firmware; or set it on the board (odrv0.axis0.config.watchdog_timeout, "
                    "enable_watchdog = True, save_configuration())"
                )
        self._watchdog_asked = watchdog
        self._endpoints = _read_endpoints(endpoints) if endpoints is not None else None

    # ---- primitives ------------------------------------------------------------------------
    def _open(self) -> None:
        self._can = import_vendor("can")
        self._bus = self.address.open(can_filters=proto.node_filter(self.node))
        self._heartbeat, self._outstanding = None, False
        try:
            reply = self._request(proto.GET_ENCODER_ESTIMATES, timeout=max(self.timeout, 0.5))
            if reply is None:
                raise DriverTimeout(
                    f"ODrive {self._who()} does not answer (no reply to Get_Encoder_Estimates): "
                    f"is it powered, is node={self.node} right (odrv0.axis0.config.can.node_id), is the bit rate right?"
                )
            self._position = proto.ESTIMATES_FORMAT.unpack_from(reply)[0]
            self._send(proto.SET_AXIS_STATE, proto.AXIS_STATE_FORMAT.pack(proto.IDLE))
            control = proto.CONTROL_MODES[self.mode]
            self._send(
                proto.SET_CONTROLLER_MODE, proto.CONTROLLER_MODE_FORMAT.pack(control, proto.INPUT_MODE_PASSTHROUGH)
            )
            self._info = self._read_identity()
            if self._watchdog_asked is not None:
                self._configure_watchdog(self._watchdog_asked)
        except BaseException:
            self._bus.shutdown()
            self._bus = None
            raise

    def _close(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            bus.shutdown()

    def _set_torque(self, enabled: bool) -> None:
        if enabled:
            self._clear_own_watchdog_error()
            self._check_heartbeat(closed_loop=False)
            # hold where it is: the first closed-loop input is the present position (or no torque)
            self._send_command(self._position if self.mode == "position" else 0.0)
        self._request_state(proto.CLOSED_LOOP_CONTROL if enabled else proto.IDLE)

    def _exchange(self, command: float, slot: int | None) -> Reading:  # noqa: ARG002 - runs on its own clock
        if self._outstanding:
            # the last exchange timed out: let its estimates arrive now rather than answer this one
            self._await(proto.GET_ENCODER_ESTIMATES, self.timeout)
            self._outstanding = False
        self._drain()
        self._check_heartbeat(closed_loop=True)
        self._send_command(command)
        reply = self._request(proto.GET_ENCODER_ESTIMATES, timeout=self.timeout, closed_loop=True)
        if reply is None:
            self._outstanding = True
            raise DriverTimeout(
                f"ODrive {self._who()}: no encoder estimates within {self.timeout * 1e3:.0f} ms (the axis stopped answering)"
            )
        position, velocity = proto.ESTIMATES_FORMAT.unpack_from(reply)
        self._position = position
        return Reading(position=position, velocity=velocity * _TWO_PI)

    def _read(self) -> Reading:
        reply = self._request(proto.GET_ENCODER_ESTIMATES, timeout=self.timeout)
        if reply is None:
            raise DriverTimeout(f"ODrive {self._who()}: no encoder estimates within {self.timeout * 1e3:.0f} ms")
        position, velocity = proto.ESTIMATES_FORMAT.unpack_from(reply)
        return Reading(position=position, velocity=velocity * _TWO_PI)

    def _identity(self) -> dict[str, Any]:
        return dict(self._info)

    # ---- frames ----------------------------------------------------------------------------
    def _send(self, command: int, data: bytes = b"", *, remote: bool = False) -> None:
        msg = self._can.Message(
            arbitration_id=proto.arbitration_id(self.node, command), data=data, is_extended_id=False,
            is_remote_frame=remote, dlc=8 if remote else len(data),
        )  # fmt: skip
        self._bus.send(msg)

    def _send_command(self, command: float) -> None:
        if self.mode == "position":
            self._send(proto.SET_INPUT_POS, proto.INPUT_POS_FORMAT.pack(command, 0, 0))
        else:
            self._send(proto.SET_INPUT_TORQUE, proto.INPUT_TORQUE_FORMAT.pack(command))

    def _request(self, command: int, *, timeout: float, closed_loop: bool | None = None) -> bytes | None:
        """Remote-request ``command`` and return its data, or None after ``timeout`` s.

        Heartbeats read while waiting are checked (``closed_loop``: whether the
        axis must be in closed-loop control; None checks nothing).
        """
        self._send(command, remote=True)
        return self._await(command, timeout, closed_loop=closed_loop)

    def _await(self, command: int, timeout: float, *, closed_loop: bool | None = None) -> bytes | None:
        """Read frames until one of ``command`` arrives (its data) or ``timeout`` s pass (None)."""
        deadline = time.perf_counter() + timeout
        while True:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                return None
            msg = self._bus.recv(remaining)
            if msg is None:
                return None
            got = self._handle(msg)
            if closed_loop is not None and got == proto.HEARTBEAT:
                self._check_heartbeat(closed_loop=closed_loop)
            if got == command:
                return bytes(msg.data)

    def _handle(self, msg: Any) -> int | None:
        """Take note of one received frame; return its command id (None for frames to ignore)."""
        if msg.is_remote_frame or msg.is_error_frame:
            return None  # our own requests, echoed by interfaces that loop frames back
        node, command = proto.split_id(msg.arbitration_id)
        if node != self.node:
            return None
        if command == proto.HEARTBEAT and len(msg.data) >= 5:
            self._heartbeat = proto.Heartbeat.decode(bytes(msg.data))
            self._beats += 1
        return int(command)

    def _drain(self) -> None:
        """Handle every frame already waiting (heartbeats, late replies) before a new exchange."""
        while (msg := self._bus.recv(0.0)) is not None:
            self._handle(msg)

    def _request_state(self, state: int) -> None:
        """Set_Axis_State, then wait for a heartbeat sent after it that shows ``state``."""
        self._drain()
        seen = self._beats
        self._send(proto.SET_AXIS_STATE, proto.AXIS_STATE_FORMAT.pack(state))
        deadline = time.perf_counter() + STATE_TIMEOUT_S
        while True:
            beat = self._heartbeat
            if self._beats > seen and beat is not None:
                if beat.axis_state == state and (state == proto.IDLE or not beat.axis_error):
                    return  # an axis that disarmed on an error is off, which is what IDLE asks for
                if beat.axis_error:
                    self._fault(beat)
            remaining = deadline - time.perf_counter()
            msg = self._bus.recv(remaining) if remaining > 0 else None
            if msg is None:
                now = "no heartbeat" if self._beats == seen or beat is None else beat.describe()
                raise DriverTimeout(
                    f"ODrive {self._who()} did not confirm {proto.state_name(state)} within {STATE_TIMEOUT_S:g} s ({now})"
                )
            self._handle(msg)

    def _check_heartbeat(self, *, closed_loop: bool) -> None:
        beat = self._heartbeat
        if beat is None:
            return
        if beat.axis_error:
            self._fault(beat)
        if closed_loop and beat.axis_state != proto.CLOSED_LOOP_CONTROL:
            raise DeviceFault(f"ODrive {self._who()} left closed-loop control: {beat.describe()}")

    def _fault(self, beat: proto.Heartbeat) -> None:
        detail = ""
        reply = self._request(proto.GET_ERROR, timeout=min(self.timeout, 0.05))
        if reply is not None and len(reply) >= proto.ERROR_FORMAT.size:
            active, disarm = proto.ERROR_FORMAT.unpack_from(reply)
            detail = f"; active errors 0x{active:08X}, disarm reason 0x{disarm:08X} ({proto.error_names(disarm)})"
        raise DeviceFault(f"ODrive {self._who()} reported {beat.describe()}{detail}")

    # ---- the axis watchdog -------------------------------------------------------------------------
    def _configure_watchdog(self, seconds: float) -> None:
        """Write the watchdog's timeout, then whether it is on (RxSdo), and read both back (TxSdo)."""
        assert self._endpoints is not None
        firmware, table = self._endpoints
        found = self._info.get("firmware_version")
        if found is not None and found != firmware:
            raise ConfigError(
                f"the endpoints file is for firmware {firmware}, ODrive {self._who()} runs {found}: its ids would "
                "name other settings; give the board's own flat_endpoints.json"
            )
        wanted = {proto.WATCHDOG_ENDPOINTS[0]: float(seconds), proto.WATCHDOG_ENDPOINTS[1]: seconds > 0}
        for name, value in wanted.items():
            ident, kind = table[name]
            self._send(proto.RXSDO, proto.SDO_FORMAT.pack(proto.SDO_WRITE, ident, 0, proto.sdo_value(kind, value)))
        for name, value in wanted.items():
            ident, kind = table[name]
            got = self._read_endpoint(ident, kind)
            if got is None or (got != value and not (kind == "float" and abs(float(got) - float(value)) < 1e-6)):
                raise ProtocolError(f"ODrive {self._who()} did not take {name} = {value} (it reads {got!r})")
        self.watchdog_s = seconds or None

    def _read_endpoint(self, ident: int, kind: str) -> float | bool | int | None:
        self._send(proto.RXSDO, proto.SDO_FORMAT.pack(proto.SDO_READ, ident, 0, bytes(4)))
        deadline = time.perf_counter() + max(self.timeout, 0.05)
        while (remaining := deadline - time.perf_counter()) > 0:
            reply = self._await(proto.TXSDO, remaining)
            if reply is None:
                return None
            _, got_id, _, value = proto.SDO_FORMAT.unpack_from(reply)
            if got_id == ident:
                return proto.sdo_decode(kind, value)
        return None

    def _clear_own_watchdog_error(self) -> None:
        """Clear WATCHDOG_TIMER_EXPIRED alone (the last host died): the axis disarmed as it should have."""
        beat = self._heartbeat
        if beat is not None and beat.axis_error == proto.WATCHDOG_TIMER_EXPIRED:
            self._send(proto.CLEAR_ERRORS)
            self._heartbeat = None  # the next heartbeat tells whether it is clear

    def _read_identity(self) -> dict[str, Any]:
        info: dict[str, Any] = {"driver": "can", "protocol": "ODrive CAN Simple", "node": self.node, "mode": self.mode}
        if self.node == 0:
            return info  # id 0x000 is CANopen NMT on firmware 0.5: do not send a remote frame there
        reply = self._request(proto.GET_VERSION, timeout=min(self.timeout, 0.05))
        if reply is not None and len(reply) >= proto.VERSION_FORMAT.size:
            v = proto.VERSION_FORMAT.unpack_from(reply)
            info.update(
                protocol_version=v[0], hardware_version=f"{v[1]}.{v[2]}.{v[3]}",
                firmware_version=f"{v[4]}.{v[5]}.{v[6]}" + ("-dev" if v[7] else ""),
            )  # fmt: skip
        return info
