"""A simulated ODrive axis speaking CAN Simple, with a twin (or the bench plant) behind it.

It answers what :class:`~servoid.drivers.can.odrive.OdriveDriver` and a user's
own CAN Simple code send: Set_Axis_State (IDLE / CLOSED_LOOP_CONTROL),
Set_Controller_Mode, Set_Input_Pos, Set_Input_Torque, Clear_Errors, Estop, and
remote requests for Get_Encoder_Estimates, Get_Error, Get_Version and the
heartbeat; it sends a heartbeat every ``heartbeat_ms`` and at once on every
change of axis state or error.

Samples (see :mod:`servoid.drivers.can._sim_axis`): each Set_Input_Pos (or
Set_Input_Torque) is one sample of the plant, in closed-loop control only;
the estimates then report the new position. CAN Simple carries no sample
number, so how many samples lie between two inputs is the axis's own
business, as on a real ODrive, whose loop runs on its own clock:

* ``period_s`` given: the axis runs on its own clock at that period -- an
  input that comes ``n`` periods after the previous one (rounded) first runs
  ``n - 1`` samples on the held input. Sample at the axis's period, or the
  plant seen is another. (The estimates report the latest sample: held
  samples are counted when the next input comes, so that a request the host
  sends late does not commit a sample the next input belongs to.)
* no period: each input is one sample, whatever the time between them (the
  inputs are the clock; a slot the host skips is not seen).
* ``slot_source`` (in-process tests only): a callable that returns the host's
  slot number of the input being handled (the slot each command was sent with),
  told out of band because the protocol has no room for it; the axis then
  follows the host's slots exactly, as the CiA 402 drive does from its SYNC
  counter.

The servo (:mod:`servoid.drivers.servos`, default the ``odrive`` twin) is
reported as an ODrive reports it: positions in turns (Set_Input_Pos,
Get_Encoder_Estimates) of the shaft whose encoder the loop uses -- the
motor's, unless the twin closes its loop on the load encoder
(``loop_encoder=load``, an ODrive 0.6 with ``load_encoder`` set to it) --
and the estimates are the drive's own encoder PLL's, position and
velocity. A twin that turns its output off by itself (overspeed, past
``vel_limit_tolerance`` times ``vel_limit``) disarms the axis with
VELOCITY_LIMIT_VIOLATION in the heartbeat, as the firmware does. Torque
control drives a twin's current loop on the input torque (N m at the motor);
asked of a twin without one, the axis reports BAD_CONFIG. With the
pseudo-Wiener plant (``servo="model"``) positions are turns of the plant's
output, as before the twins.

The axis watchdog (``config.enable_watchdog``, ``config.watchdog_timeout``),
as the firmware runs it: every frame addressed to the axis feeds it (CAN
Simple's ``do_command`` does so before anything else), and in closed-loop
control a silence longer than the timeout disarms the axis to IDLE with
WATCHDOG_TIMER_EXPIRED. Both settings can be given as saved on the board
(``watchdog_s``) or written over RxSdo with the ids of
:meth:`SimOdriveAxis.flat_endpoints` (this simulated firmware's endpoint
table, as a real board's ``flat_endpoints.json`` gives its own).
``on_event`` hears the watchdog expiring and the power stage going off.

Faults for tests: :meth:`SimOdriveAxis.inject_axis_error` (the axis disarms
to IDLE and says why in the heartbeat, as the firmware does), applied at
the next Set_Input_* so that tests are deterministic, as is
:meth:`SimOdriveAxis.inject_reboot` (back in IDLE without an error);
:meth:`SimOdriveAxis.mute` and ``mute_after`` (receives and obeys, sends
nothing), ``drop`` (estimates lost now and then in closed-loop control).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

from servoid import readings_side, validation
from servoid.drivers.can import odrive_protocol as proto
from servoid.drivers.can._bus import BusAddress, import_vendor
from servoid.drivers.can._sim_axis import TORQUE_GAIN
from servoid.drivers.can._sim_base import SimDrive
from servoid.drivers.can.driver import DEFAULT_NODES
from servoid.drivers.servos import Servo, parse_servo
from servoid.errors import ConfigError

__all__ = ["SimOdriveAxis", "SIM_VERSION"]

#: What the simulated axis answers to Get_Version: protocol 2, hardware 0.0.0 (none), firmware 0.6.10.
SIM_VERSION = (2, 0, 0, 0, 0, 6, 10, 0)

_TWO_PI = 2 * math.pi

#: Axis error for torque control asked of a twin without a current loop.
_BAD_CONFIG = next(bit for bit, name in proto.AXIS_ERRORS.items() if name == "BAD_CONFIG")

#: Axis error of a twin that turned its output off on overspeed (ODrive 0.6's name for it).
_OVERSPEED = next(bit for bit, name in proto.AXIS_ERRORS.items() if name == "VELOCITY_LIMIT_VIOLATION")

#: Data frames only the axis sends (the host asks for them with remote frames).
_SENT_BY_THE_AXIS = frozenset({proto.GET_VERSION, proto.HEARTBEAT, proto.GET_ERROR, proto.TXSDO,
                               proto.GET_ENCODER_ESTIMATES})  # fmt: skip

#: This simulated firmware's endpoints (name -> id, type); a real board's ids come from its flat_endpoints.json.
_ENDPOINTS = {"axis0.config.watchdog_timeout": (0x0101, "float"), "axis0.config.enable_watchdog": (0x0102, "bool")}


class SimOdriveAxis(SimDrive):
    """A simulated ODrive axis on a python-can bus (see the module docstring).

    Parameters
    ----------
    node : int
        CAN Simple node id, 0..63.
    bus, torque_gain
        As for :class:`~servoid.drivers.can._sim_base.SimDrive`.
    servo : Servo or str
        The servo behind the axis (default the ``odrive`` twin; text as
        :func:`~servoid.drivers.servos.parse_servo` reads it: ``"model"``,
        ``"odrive?loop_encoder=load"``).
    heartbeat_ms : float
        Period of the cyclic heartbeat, ms (ODrive's default 100).
    period_s : float, optional
        The axis's own sample period (see the module docstring); None: one
        sample per input.
    mute_after, drop, seed
        Injected faults (:class:`~servoid.drivers.can._sim_base.SimDrive`),
        counted in encoder estimates sent in closed-loop control.
    watchdog_s : float, optional
        The axis watchdog as saved on the board (``config.watchdog_timeout``
        with ``config.enable_watchdog``); None: off.

    Attributes
    ----------
    slot_source : callable or None
        In-process tests: returns the host's slot of the input being handled.
    """

    protocol = "odrive"

    def __init__(
        self,
        *,
        node: int = DEFAULT_NODES["odrive"],
        bus: BusAddress | None = None,
        servo: Servo | str = "odrive",
        torque_gain: float = TORQUE_GAIN,
        heartbeat_ms: float = 100.0,
        period_s: float | None = None,
        mute_after: int | None = None,
        drop: float = 0.0,
        seed: int = 0,
        watchdog_s: float | None = None,
    ) -> None:
        node = validation.integer("node", node, minimum=0)
        if node > 63:
            raise ConfigError(f"node (={node}) must be 0..63 for ODrive CAN Simple")
        servo = servo if isinstance(servo, Servo) else parse_servo(servo)
        super().__init__(
            node=node, bus=bus, servo=servo, torque_gain=torque_gain, period_s=period_s, mute_after=mute_after,
            drop=drop, seed=seed,
        )  # fmt: skip
        twin = servo.twin
        #: Turns of the shaft the axis counts per turn of the output (its loop encoder's shaft).
        self.turns_per_output_turn = 1.0 if twin is None or twin.loop_encoder == "load" else twin.gear_ratio
        #: Which shaft the estimates are of (the driver's ``readings=``): the motor's when the loop is on it.
        self.readings_side = (
            readings_side.MOTOR if twin is not None and twin.loop_encoder == "motor" else readings_side.OUTPUT
        )
        self.heartbeat_s = validation.positive("heartbeat_ms", heartbeat_ms) / 1000.0
        self.slot_source: Callable[[], int | None] | None = None
        self._axis_state = proto.IDLE
        self.axis_error = 0
        self.control_mode = proto.CONTROL_MODES["position"]
        self.inputs = 0
        self._input = 0.0
        self._pending_error = 0
        self._pending_reboot = False
        self._can: Any = None
        self._bus: Any = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.watchdog_timeout = 0.0 if watchdog_s is None else validation.positive("watchdog_s", watchdog_s)
        self.enable_watchdog = watchdog_s is not None
        self._fed = time.monotonic()  # when a frame for the axis last came

    def url(self, **options: Any) -> str:
        """The ``can://`` URL that reaches this axis, with ``readings=`` saying which shaft its estimates are of."""
        return super().url(**{readings_side.METADATA_KEY: self.readings_side, **options})

    # ---- life cycle ----------------------------------------------------------------------
    def start(self) -> SimOdriveAxis:
        """Connect to the bus and start answering (in a thread of its own)."""
        if self._bus is not None:
            return self
        self._can = import_vendor("can")
        self._bus = self.bus.open(can_filters=proto.node_filter(self.node))
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, name=f"sim-odrive-{self.node}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Leave the bus; idempotent."""
        if self._bus is None:
            return
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._bus.shutdown()
        self._bus, self._thread = None, None

    # ---- what tests look at ----------------------------------------------------------------
    @property
    def axis_state(self) -> int:
        """IDLE (1), CLOSED_LOOP_CONTROL (8), ..."""
        return self._axis_state

    @axis_state.setter
    def axis_state(self, state: int) -> None:
        was_on = self._axis_state == proto.CLOSED_LOOP_CONTROL
        self._axis_state = state
        self.axis.power(state == proto.CLOSED_LOOP_CONTROL)
        if state == proto.CLOSED_LOOP_CONTROL:
            self._fed = time.monotonic()  # the watchdog counts from entering closed loop
        elif was_on:
            self._event(f"power stage off ({proto.state_name(state)})")

    @staticmethod
    def flat_endpoints() -> dict[str, Any]:
        """This simulated firmware's endpoint table, in the shape of a board's ``flat_endpoints.json``."""
        return {
            "fw_version": ".".join(map(str, SIM_VERSION[4:7])),
            "hw_version": ".".join(map(str, SIM_VERSION[1:4])),
            "endpoints": {name: {"id": ident, "type": kind, "access": "rw"}
                          for name, (ident, kind) in _ENDPOINTS.items()},
        }  # fmt: skip

    @property
    def power_on(self) -> bool:
        """Whether the axis is in closed-loop control (the power stage on)."""
        return self.axis_state == proto.CLOSED_LOOP_CONTROL

    def status(self) -> str:
        """One line for a terminal."""
        beat = proto.Heartbeat(self.axis_error, self.axis_state).describe()
        return f"node {self.node}: {beat}, {self.inputs} inputs, position {self.axis.position:+.4f} rad"

    def estimates(self) -> tuple[float, float]:
        """Get_Encoder_Estimates: position (turns) and velocity (turns/s) of the loop encoder's shaft.

        A twin's are its encoder PLL's, as of the latest sample; the
        pseudo-Wiener plant's, its output and the change of it over the
        time between its last two samples.
        """
        reading = self.axis.reading
        if reading is None:
            return self.axis.position / _TWO_PI, self.axis.velocity / _TWO_PI
        scale = self.turns_per_output_turn / _TWO_PI
        return reading.position_estimate_rad * scale, reading.velocity_rad_s * scale

    # ---- fault injection -------------------------------------------------------------------
    def inject_axis_error(self, code: int = 0x1000) -> None:
        """At the next Set_Input_*: set axis error ``code`` (default CURRENT_LIMIT_VIOLATION) and disarm."""
        self._pending_error = code

    def inject_reboot(self) -> None:
        """At the next Set_Input_*: the board reboots (a brown-out): IDLE, no error, default controller mode."""
        self._pending_reboot = True

    # ---- the server thread -----------------------------------------------------------------
    def _serve(self) -> None:
        next_beat = time.perf_counter()
        while not self._stop.is_set():
            now = time.perf_counter()
            if now >= next_beat:
                self._send_heartbeat()
                next_beat = now + self.heartbeat_s
            msg = self._bus.recv(min(next_beat - now, 0.005 if self._watching() else 0.05))
            if msg is not None:
                self._on_frame(msg)
            self._check_watchdog()

    def _watching(self) -> bool:
        return self.enable_watchdog and self.watchdog_timeout > 0 and self.power_on

    def _check_watchdog(self) -> None:
        if self._watching() and time.monotonic() - self._fed > self.watchdog_timeout:
            silent = time.monotonic() - self._fed
            self._event(f"axis watchdog expired ({silent * 1e3:.0f} ms without a frame): WATCHDOG_TIMER_EXPIRED")
            self._disarm(proto.WATCHDOG_TIMER_EXPIRED)

    def _on_frame(self, msg: Any) -> None:
        if msg.is_error_frame:
            return
        node, command = proto.split_id(msg.arbitration_id)
        if node != self.node:
            return
        if not msg.is_remote_frame and command in _SENT_BY_THE_AXIS:
            return  # the axis's own frame, looped back by the UDP bus: a CAN controller never receives its own
        self._fed = time.monotonic()  # any frame for the axis feeds its watchdog, as CAN Simple's do_command
        at = msg.timestamp or time.time()  # when the bus took the frame (the kernel's stamp over UDP)
        if msg.is_remote_frame:
            self._answer(command)
            return
        data = bytes(msg.data)
        if command == proto.SET_INPUT_POS and len(data) >= proto.INPUT_POS_FORMAT.size:
            turns = proto.INPUT_POS_FORMAT.unpack_from(data)[0]
            self._on_input(turns * _TWO_PI / self.turns_per_output_turn, torque=False, at=at)
        elif command == proto.SET_INPUT_TORQUE and len(data) >= proto.INPUT_TORQUE_FORMAT.size:
            self._on_input(proto.INPUT_TORQUE_FORMAT.unpack_from(data)[0], torque=True, at=at)
        elif command == proto.SET_AXIS_STATE and len(data) >= proto.AXIS_STATE_FORMAT.size:
            self._on_state_request(proto.AXIS_STATE_FORMAT.unpack_from(data)[0])
        elif command == proto.SET_CONTROLLER_MODE and len(data) >= proto.CONTROLLER_MODE_FORMAT.size:
            self.control_mode = proto.CONTROLLER_MODE_FORMAT.unpack_from(data)[0]
            if self.control_mode == proto.CONTROL_MODES["torque"] and not self.axis.torque_capable:
                self._disarm(_BAD_CONFIG)  # a twin without a current loop: the configuration cannot run
        elif command == proto.CLEAR_ERRORS:
            self.axis_error = 0
            self._send_heartbeat()
        elif command == proto.ESTOP:
            self._disarm(0x2000000)  # ESTOP_REQUESTED
        elif command == proto.RXSDO and len(data) >= proto.SDO_FORMAT.size:
            self._on_sdo(*proto.SDO_FORMAT.unpack_from(data))

    def _on_sdo(self, opcode: int, ident: int, _reserved: int, value: bytes) -> None:
        name = next((n for n, (i, _) in _ENDPOINTS.items() if i == ident), None)
        if name is None:
            return  # an id this firmware does not have: no answer
        kind = _ENDPOINTS[name][1]
        attribute = name.rsplit(".", 1)[1]
        if opcode == proto.SDO_WRITE:
            setattr(self, attribute, proto.sdo_decode(kind, value))
        elif opcode == proto.SDO_READ:
            self._send(proto.TXSDO, proto.SDO_FORMAT.pack(0, ident, 0, proto.sdo_value(kind, getattr(self, attribute))))

    def _on_input(self, value: float, *, torque: bool, at: float) -> None:
        self.inputs += 1
        if self._pending_error:
            code, self._pending_error = self._pending_error, 0
            self._disarm(code)
        if self._pending_reboot:
            self._pending_reboot = False
            self.axis_state, self.axis_error = proto.IDLE, 0
            self.control_mode = proto.CONTROL_MODES["position"]
            self._send_heartbeat()  # the first heartbeat after boot
        matches = self.control_mode == proto.CONTROL_MODES["torque" if torque else "position"]
        if self.axis_state == proto.CLOSED_LOOP_CONTROL and matches:
            slot = self.slot_source() if self.slot_source is not None else None
            self.axis.step(value, torque=torque, at=at, slot=slot)
            twin = self.axis.twin
            if twin is not None and twin.twin.read().fault == "overspeed":
                self._event("the twin's output stage turned itself off (overspeed): VELOCITY_LIMIT_VIOLATION")
                self._disarm(_OVERSPEED)

    def _on_state_request(self, requested: int) -> None:
        if requested == proto.CLOSED_LOOP_CONTROL and not self.axis_error:
            self.axis_state = proto.CLOSED_LOOP_CONTROL
        elif requested == proto.IDLE:
            self.axis_state = proto.IDLE
        self._send_heartbeat()

    def _disarm(self, code: int) -> None:
        self.axis_error |= code
        self.axis_state = proto.IDLE
        self._send_heartbeat()

    def _answer(self, command: int) -> None:
        if command == proto.GET_ENCODER_ESTIMATES:
            if self.power_on and self._reply_lost():
                return
            self._send(command, proto.ESTIMATES_FORMAT.pack(*self.estimates()))
        elif command == proto.HEARTBEAT:
            self._send_heartbeat()
        elif command == proto.GET_ERROR:
            self._send(command, proto.ERROR_FORMAT.pack(self.axis_error, self.axis_error))
        elif command == proto.GET_VERSION:
            self._send(command, proto.VERSION_FORMAT.pack(*SIM_VERSION))

    def _send_heartbeat(self) -> None:
        self._send(proto.HEARTBEAT, proto.Heartbeat(self.axis_error, self.axis_state).encode())

    def _send(self, command: int, data: bytes) -> None:
        if self._muted:
            return
        msg = self._can.Message(
            arbitration_id=proto.arbitration_id(self.node, command), data=data, is_extended_id=False
        )
        self._bus.send(msg)
