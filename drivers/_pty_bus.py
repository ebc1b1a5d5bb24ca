"""Serve emulated servos of a half-duplex serial bus on a pseudo-terminal: what the Dynamixel and Feetech emulators share.

A vendor's emulator (:mod:`servoid.drivers.dynamixel.emulator`,
:mod:`servoid.drivers.feetech.emulator`) brings its packet reader and its
bus (which instruction reaches whom, who answers); this module owns the rest,
once:

* the pseudo-terminal the vendor's SDK opens unmodified (``os.openpty``, the
  slave kept open so that reads of the master never fail with EIO, the master
  non-blocking so that an emulator nobody reads never blocks);
* the serving loop (:meth:`PtyBusEmulator.serve_forever`): a partial frame is
  dropped when the line stays quiet :data:`IDLE_DISCARD_S`, as a servo's
  packet timeout does; the bus's own timers (a Dynamixel's Bus Watchdog) run
  between packets;
* the faults a test injects on one servo's link (:class:`LinkFaults`) and on
  the whole line (``flip``: a bit flipped per byte hit, each direction), each
  servo's reply sent after its Return Delay Time;
* a bus of servos looked up by their current ID, with servos unplugged and
  plugged back (:class:`ServoBus`);
* the same emulator in a child process for timing measurements
  (:class:`EmulatorProcess`: an emulator thread shares the interpreter lock
  with the code being measured).
"""

from __future__ import annotations

import abc
import errno
import fcntl
import os
import pickle
import select
import subprocess
import sys
import threading
import tty
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Generic, Protocol, TypeVar

import numpy as np

from servoid import validation
from servoid.drivers.clock import NS_PER_S, Clock, MonotonicClock
from servoid.drivers.realtime import collector_off_heap, make_realtime
from servoid.drivers.sampled import SampledPlant
from servoid.drivers.servos import DEFAULT_RATE_HZ, Servo, parse_servo
from servoid.drivers.twin import Twin, TwinPlant
from servoid.errors import ConfigError, DriverError
from servoid.ident.models.plant import Plant

__all__ = ["IDLE_DISCARD_S", "LinkFaults", "EmulatorStats", "BusServo", "ServoBus", "PtyBusEmulator", "EmulatorProcess",
           "servo_plant", "bus_servos", "return_delay_units"]  # fmt: skip

#: A partial frame is dropped when the line stays quiet this long (s), as a servo's packet timeout does.
IDLE_DISCARD_S = 0.05


def servo_plant(servo: Servo | str, period_s: float | None) -> tuple[Servo, SampledPlant]:
    """The servo named by ``servo`` and its plant as an emulated bus servo samples it (twin: drive stage off).

    Parameters
    ----------
    servo : Servo or str
        The mechanics (:func:`~servoid.drivers.servos.parse_servo`'s text, or a parsed one).
    period_s : float or None
        The servo's own sample period; None: one sample per goal (a twin
        then runs one period at :data:`~servoid.drivers.servos.DEFAULT_RATE_HZ`).
    """
    spec = servo if isinstance(servo, Servo) else parse_servo(servo)
    period_ns = None if period_s is None else int(round(validation.positive("period_s", period_s) * NS_PER_S))
    if spec.twin is None:
        assert spec.model is not None
        return spec, SampledPlant(spec.model, period_ns=period_ns)
    twin = TwinPlant(Twin(spec.twin), 1.0 / DEFAULT_RATE_HZ, torque=False)
    return spec, SampledPlant(twin, period_ns=period_ns)


def return_delay_units(servo_id: int, return_delay_us: int, *, max_id: int) -> int:
    """Check an emulated servo's ID and Return Delay Time; the delay in its 2 us units.

    Parameters
    ----------
    servo_id : int
        The servo's ID.
    return_delay_us : int
        Microseconds, even, 0..508.
    max_id : int
        The highest ID the protocol allows.
    """
    validation.integer("servo_id", servo_id, minimum=0)
    if servo_id > max_id:
        raise ConfigError(f"servo_id (={servo_id}) must be in 0..{max_id}")
    delay = validation.integer("return_delay_us", return_delay_us, minimum=0)
    if delay > 508 or delay % 2:
        raise ConfigError(f"return_delay_us (={delay}) must be even and in 0..508 (unit 2 us)")
    return delay // 2


def bus_servos(ids: Iterable[int], servo: Servo | str, make: Callable[[int, Servo], S]) -> list[S]:
    """One emulated servo per ID, ``make(id, spec)``, with the plant's kernels compiled now (not while a reply is awaited).

    Parameters
    ----------
    ids : iterable of int
        Distinct IDs.
    servo : Servo or str
        The mechanics behind each.
    make : callable
        Builds one servo.
    """
    id_list = [int(i) for i in ids]
    if not id_list or len(set(id_list)) != len(id_list):
        raise ConfigError(f"ids (={id_list}) must be one or more distinct servo IDs")
    spec = servo if isinstance(servo, Servo) else parse_servo(servo)
    if spec.model is not None:
        Plant(spec.model).step(0.0)
    else:
        Twin(spec.twin).advance(1e-3)  # type: ignore[arg-type]
    return [make(i, spec) for i in id_list]


class BusServo(Protocol):
    """What the bus needs of an emulated servo."""

    @property
    def id(self) -> int: ...

    @property
    def return_delay_s(self) -> float: ...


S = TypeVar("S", bound=BusServo)


@dataclass
class LinkFaults:
    """Faults injected on one servo's link; change the fields while the emulator runs.

    Attributes
    ----------
    mute : bool
        The servo still executes instructions but never answers (a broken
        return line): every read times out, yet a torque-off write still
        reaches it.
    corrupt_replies : int
        Corrupt the checksum (CRC) of this many of the servo's next status packets.
    corrupt_requests : int
        Treat this many of the next instruction packets addressed to the servo
        as received corrupted (a Dynamixel answers with the CRC error number,
        a Feetech servo drops it unanswered).
    stale_replies : int
        Answer this many of the next READs with an empty status packet, as a
        late answer to an earlier WRITE would look to the SDK (success, but no
        data).
    late_replies : int
        Send this many of the servo's next answers to READs twice: the copy
        stays in the host's input, as an answer that came after its request
        had timed out would, and passes for the answer to the next READ unless
        the host drops what waits in its input before a request.
    mute_after : int, optional
        Set ``mute`` after the servo sent this many more status packets (counts down).
    drop : float
        Probability that a status packet is lost on the way back.
    corrupt_goals : int
        Treat this many of the next SYNC_WRITE packets on the bus as received
        corrupted: every servo drops them, unanswered (a goal lost on its
        way, which only a read-back of the goal shows).
    corrupt_lengths : int
        Send this many of the servo's next status packets with their LENGTH
        field cut short (fewer bytes than the packet's own header holds), the
        rest of the packet unchanged.
    """

    mute: bool = False
    corrupt_replies: int = 0
    corrupt_requests: int = 0
    corrupt_goals: int = 0
    corrupt_lengths: int = 0
    stale_replies: int = 0
    late_replies: int = 0
    mute_after: int | None = None
    drop: float = 0.0


@dataclass
class EmulatorStats:
    """What the emulator saw: packets received, status packets sent, frames with a bad CRC or checksum."""

    received: int = 0
    replies: int = 0
    corrupt_received: int = 0
    dropped_replies: int = 0
    flipped_bits: int = 0


class ServoBus(Generic[S]):
    """Several servos on one bus, looked up by their current ID (a WRITE of ID can change it).

    Parameters
    ----------
    servos : iterable
        The servos on the bus.
    """

    def __init__(self, servos: Iterable[S]) -> None:
        self.servos = list(servos)
        self._detached: set[int] = set()  # id() of unplugged servos

    def find(self, servo_id: int) -> S | None:
        """The connected servo that currently has ``servo_id``."""
        for servo in self.servos:
            if id(servo) not in self._detached and servo.id == servo_id:
                return servo
        return None

    def connected(self) -> list[S]:
        """The servos on the bus, by ID."""
        return sorted((s for s in self.servos if id(s) not in self._detached), key=lambda s: s.id)

    def detach(self, servo: S) -> None:
        """Take ``servo`` off the bus."""
        self._detached.add(id(servo))

    def attach(self, servo: S) -> None:
        """Put ``servo`` back on the bus."""
        self._detached.discard(id(servo))


class PtyBusEmulator(abc.ABC, Generic[S]):
    """Servos of one bus on a pseudo-terminal (see the module docstring); a vendor subclass handles the frames.

    A subclass implements :meth:`_handle` (one received frame -> the
    ``(servo, status packet)`` pairs to send, in order) and may override
    :meth:`_received` (what an intact frame does besides: feed a watchdog),
    :meth:`_timers` (the deadline of the next timer, and running the due
    ones), :meth:`_as_corrupt`, :meth:`_is_read`, :meth:`_is_sync_write`,
    :meth:`_empty_reply`, :meth:`_cut_length` and :meth:`_trace_line`.

    Parameters
    ----------
    servos : sequence
        The emulated servos on the bus.
    reader : object
        The vendor's packet reader (``feed(bytes) -> frames``, ``discard()``).
    clock : Clock, optional
        The servos' time and the Return Delay Time's wait (default the real clock).
    flip : float
        Probability per byte of one flipped bit, in both directions (a noisy line).
    flip_rx, flip_tx : float, optional
        The same for the instruction packets received and for the status
        packets sent; each defaults to ``flip``.
    seed : int
        Seed of the flipped bits and lost replies.
    trace : path, optional
        File to which every reading of the present values is written as it is
        sent, before any corruption (:meth:`_trace_line` says what).
    """

    #: Name of the emulator in messages and thread names.
    kind = "bus"

    def __init__(
        self,
        servos: Sequence[S],
        reader: Any,
        *,
        clock: Clock | None = None,
        flip: float = 0.0,
        flip_rx: float | None = None,
        flip_tx: float | None = None,
        seed: int = 0,
        trace: str | Path | None = None,
    ) -> None:
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        self.flip = validation.in_unit_interval("flip", flip, open_low=False, open_high=False)
        # None: follow ``flip`` (which tests may change while the emulator runs)
        self._flip_rx = None if flip_rx is None else validation.in_unit_interval("flip_rx", flip_rx, open_low=False,
                                                                                  open_high=False)  # fmt: skip
        self._flip_tx = None if flip_tx is None else validation.in_unit_interval("flip_tx", flip_tx, open_low=False,
                                                                                  open_high=False)  # fmt: skip
        self._rng = np.random.default_rng(seed)
        self._trace: IO[str] | None = open(trace, "w", encoding="ascii") if trace is not None else None  # noqa: SIM115
        self.bus: ServoBus[S] = ServoBus(servos)
        self._faults = {id(s): LinkFaults() for s in servos}
        self.stats = EmulatorStats()
        self._reader = reader
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        # the emulator must never block on a full pty when nobody reads the other side
        fcntl.fcntl(self._master, fcntl.F_SETFL, fcntl.fcntl(self._master, fcntl.F_GETFL) | os.O_NONBLOCK)
        self.port = os.ttyname(self._slave)
        self._wake_r, self._wake_w = os.pipe()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False

    # ---- the vendor's part ---------------------------------------------------------------
    @abc.abstractmethod
    def _handle(self, frame: Any) -> list[tuple[S, bytes]]:
        """Execute one received frame (intact or corrupt); the status packets to send, in order."""

    def _received(self, frame: Any, received_ns: int) -> None:  # noqa: B027 - optional
        """An intact instruction frame arrived at ``received_ns`` (a Dynamixel feeds its Bus Watchdogs)."""

    def _timers(self, now_ns: int) -> int | None:
        """Run the timers due by ``now_ns``; the next deadline (None: none)."""
        return None

    def _as_corrupt(self, frame: Any) -> Any:
        """``frame`` as received corrupted (what a bad checksum makes of it)."""
        raise NotImplementedError

    def _is_corrupt(self, frame: Any) -> bool:
        return False

    def _is_instruction(self, frame: Any) -> bool:
        """An intact instruction packet (not another device's status packet)."""
        return not self._is_corrupt(frame)

    def _is_read(self, frame: Any) -> bool:
        return False

    def _is_sync_write(self, frame: Any) -> bool:
        return False

    def _empty_reply(self, servo: S) -> bytes:
        """A status packet without data (what ``stale_replies`` sends)."""
        raise NotImplementedError

    def _cut_length(self, reply: bytes) -> bytes:
        """``reply`` with its LENGTH field cut below what its own header holds."""
        raise NotImplementedError

    def _trace_line(self, servo: S, frame: Any, reply: bytes) -> str | None:
        """The trace line for ``reply`` (a reading of the present values), or None."""
        return None

    # ---- access for tests and users -----------------------------------------------------
    @property
    def flip_rx(self) -> float:
        """Bit-flip probability per byte of the instruction packets received."""
        return self.flip if self._flip_rx is None else self._flip_rx

    @property
    def flip_tx(self) -> float:
        """Bit-flip probability per byte of the status packets sent."""
        return self.flip if self._flip_tx is None else self._flip_tx

    def servo(self, servo_id: int) -> S:
        """The servo that has ``servo_id`` now (also when unplugged)."""
        for s in self.bus.servos:
            if s.id == servo_id:
                return s
        raise ConfigError(f"servo_id (={servo_id}) is not on this bus; IDs: {[s.id for s in self.bus.servos]}")

    def faults(self, servo_id: int) -> LinkFaults:
        """The faults injected on a servo's link (mutable)."""
        return self._faults[id(self.servo(servo_id))]

    def unplug(self, servo_id: int) -> None:
        """Take a servo off the bus: it neither executes nor answers anything."""
        self.bus.detach(self.servo(servo_id))

    def plug(self, servo_id: int) -> None:
        """Put an unplugged servo back on the bus."""
        self.bus.attach(self.servo(servo_id))

    # ---- serving ------------------------------------------------------------------------------
    def start(self) -> PtyBusEmulator[S]:
        """Serve from a daemon thread (for logic tests; timing needs :class:`EmulatorProcess`)."""
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self.serve_forever, name=f"{self.kind} {self.port}", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving (the pty stays open until :meth:`close`)."""
        self._stop.set()
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._thread = None

    def close(self) -> None:
        """Stop and close the pseudo-terminal; safe to call twice."""
        if self._closed:
            return
        self.stop()
        self._closed = True
        if self._trace is not None:
            self._trace.close()
        for fd in (self._master, self._slave, self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> Any:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def serve_forever(self) -> None:
        """Answer packets until :meth:`stop` (or Ctrl-C when run in the foreground); run the bus's timers."""
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master, self._wake_r], [], [], self._quiet_for_s())
            self._timers(self.clock.now_ns())
            if self._wake_r in ready:
                os.read(self._wake_r, 64)
                continue
            if not ready:
                self._reader.discard()
                continue
            try:
                data = os.read(self._master, 4096)
            except BlockingIOError:
                continue
            except OSError as exc:  # the pty went away
                if exc.errno == errno.EIO:
                    break
                raise
            received = self.clock.now_ns()
            for frame in self._reader.feed(self._flipped(data, self.flip_rx)):
                self._serve_frame(frame, received)

    def _quiet_for_s(self) -> float:
        """How long to wait for bytes: until a partial frame is stale, or the next timer is due."""
        deadline = self._timers(self.clock.now_ns())
        if deadline is None:
            return IDLE_DISCARD_S
        return min(IDLE_DISCARD_S, max(0.0, (deadline - self.clock.now_ns()) / NS_PER_S))

    def _flipped(self, data: bytes, probability: float) -> bytes:
        """``data`` with one random bit flipped in each byte hit (``probability`` per byte)."""
        if not probability:
            return data
        hit = np.flatnonzero(self._rng.random(len(data)) < probability)
        if not hit.size:
            return data
        out = bytearray(data)
        for i in hit:
            out[i] ^= 1 << int(self._rng.integers(8))
        self.stats.flipped_bits += int(hit.size)
        return bytes(out)

    def _serve_frame(self, frame: Any, received: int) -> None:
        self.stats.received += 1
        if self._is_instruction(frame):
            target = self.bus.find(frame.id)
            if target is not None and self._faults[id(target)].corrupt_requests > 0:
                self._faults[id(target)].corrupt_requests -= 1
                frame = self._as_corrupt(frame)
            elif self._is_sync_write(frame):
                losing = next((f for f in self._faults.values() if f.corrupt_goals > 0), None)
                if losing is not None:
                    losing.corrupt_goals -= 1
                    frame = self._as_corrupt(frame)
        if self._is_corrupt(frame):
            self.stats.corrupt_received += 1
        elif self._is_instruction(frame):
            self._received(frame, received)
        last = received
        for servo, reply in self._handle(frame):
            faults = self._faults[id(servo)]
            if faults.mute_after is not None and faults.mute_after <= 0:
                faults.mute = True
            if faults.mute:
                continue
            if faults.mute_after is not None:
                faults.mute_after -= 1
            if faults.drop and self._rng.random() < faults.drop:
                self.stats.dropped_replies += 1
                continue
            if faults.stale_replies > 0 and self._is_read(frame):
                faults.stale_replies -= 1
                reply = self._empty_reply(servo)
            elif self._trace is not None:
                line = self._trace_line(servo, frame, reply)
                if line is not None:
                    self._trace.write(line + "\n")
                    self._trace.flush()
            if faults.corrupt_replies > 0:
                faults.corrupt_replies -= 1
                reply = reply[:-1] + bytes((reply[-1] ^ 0xFF,))
            if faults.corrupt_lengths > 0:
                faults.corrupt_lengths -= 1
                reply = self._cut_length(reply)
            # each servo waits its Return Delay Time after the bus went quiet
            self.clock.sleep_until_ns(last + round(servo.return_delay_s * NS_PER_S))
            copies = 1
            if faults.late_replies > 0 and self._is_read(frame):
                faults.late_replies -= 1
                copies = 2
            for _ in range(copies):
                try:
                    os.write(self._master, self._flipped(reply, self.flip_tx))
                    self.stats.replies += 1
                except BlockingIOError:
                    self.stats.dropped_replies += 1
            last = self.clock.now_ns()


def serve_child(make: Callable[..., PtyBusEmulator[Any]]) -> None:
    """Entry of the child process of :class:`EmulatorProcess`.

    Reads the pickled ``(ids, options)`` from stdin, builds ``make(ids, **options)``,
    prints its port on stdout, and serves until stdin closes (the parent
    stopped it, or went away).

    Parameters
    ----------
    make : callable
        The emulator class.
    """
    ids, options = pickle.load(sys.stdin.buffer)
    make_realtime()  # the device's clock first, where permitted (servoid.drivers.realtime); before its threads
    # and the garbage collector off its heap: a full collection holds the device's replies and its watchdog
    with make(ids, **options) as emulator, collector_off_heap():
        print(emulator.port, flush=True)
        sys.stdin.buffer.read()


class EmulatorProcess:
    """An emulator in a child process, for timing measurements.

    The child is a fresh interpreter (``python -m <module>``, a vendor
    emulator's module, whose ``__main__`` calls :func:`serve_child`), so this
    works from any script, with or without an ``if __name__ == "__main__"`` guard.
    A vendor subclass sets :attr:`module`, :attr:`kind` and :meth:`url`.

    Parameters
    ----------
    ids : iterable of int
        Servo IDs on the bus.
    **options
        Passed to the emulator (all but ``clock``).
    """

    #: The module run in the child.
    module = ""
    #: Name in messages.
    kind = "servo"

    def __init__(self, ids: Iterable[int] = (1,), **options: Any) -> None:
        if "clock" in options:
            raise ConfigError("clock cannot be given to an emulator in another process; use the emulator class")
        self.ids = [int(i) for i in ids]
        self._options = options
        self._process: subprocess.Popen[bytes] | None = None
        self.port = ""

    def start(self, timeout: float = 60.0) -> Any:
        """Start the child and wait for its port; returns self."""
        self._process = subprocess.Popen(
            [sys.executable, "-m", self.module], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        assert self._process.stdin is not None and self._process.stdout is not None
        pickle.dump((self.ids, self._options), self._process.stdin)
        self._process.stdin.flush()
        ready, _, _ = select.select([self._process.stdout], [], [], timeout)
        line = self._process.stdout.readline().decode().strip() if ready else ""
        if not line:
            error = b"" if self._process.poll() is None else self._process.stderr.read()  # type: ignore[union-attr]
            self.stop()
            raise DriverError(
                f"the {self.kind} emulator process did not start within {timeout} s: {error.decode().strip()}"
            )
        self.port = line
        return self

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the child process; safe to call twice."""
        process, self._process = self._process, None
        if process is None:
            return
        try:
            process.stdin.close()  # type: ignore[union-attr]
            process.wait(timeout)
        except (OSError, subprocess.TimeoutExpired):
            process.kill()
            process.wait(timeout)
        finally:
            for stream in (process.stdout, process.stderr):
                if stream is not None:
                    stream.close()

    def __enter__(self) -> Any:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
