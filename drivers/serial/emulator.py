"""Run the reference firmware, built for the host, as a serial servo on a pseudo-terminal.

:class:`FirmwareEmulator` starts the compiled firmware (see
:mod:`servoid.drivers.serial.build`) as its own process, which opens a
pseudo-terminal, prints its name and serves it: the real pyserial driver
talks to the real firmware code. Behind the HAL is the servo
(:mod:`servoid.drivers.servos`): a physical twin in C (``firmware/host/twin_sim.c``,
the port of the Python twin's physics), whose loop is the firmware's own
(``firmware/loop.c``, the port of the twin's firmware) running at the
twin's ticks -- the split of a real board, where the bench controller runs
the position loop on its encoder and drives PWM through the HAL -- or the
pseudo-Wiener model (``servo="model"``), which is loop and plant in one. The
default is the ``xm430`` twin: its structure (a position PID on the output
encoder driving PWM, no current sensing) is what a bench board with an
H-bridge and a geared motor runs, and its numbers are the best sourced of
the presets. It runs in a separate process so that it does not share the
interpreter lock with the sampler (HARDWARE.md).

Example
-------
>>> with FirmwareEmulator() as emu:            # doctest: +SKIP
...     with driver_from_url(emu.url) as servo:
...         servo.enable()
...         servo.exchange(0.1)
"""

from __future__ import annotations

import math
import os
import select
import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from typing import IO

from servoid import validation
from servoid.drivers.realtime import make_realtime
from servoid.drivers.serial.build import firmware_binary
from servoid.drivers.servos import DEFAULT_SERVO, Servo, parse_servo
from servoid.errors import ConfigError, DriverError

__all__ = ["FirmwareOptions", "FirmwareEmulator"]

#: How long the firmware may take to print its port.
START_TIMEOUT_S = 10.0


@dataclass(frozen=True, kw_only=True)
class FirmwareOptions:
    """How the emulated bench servo behaves.

    Parameters
    ----------
    servo : Servo or str
        The servo behind the HAL (default the ``xm430`` twin; text as
        :func:`~servoid.drivers.servos.parse_servo` reads it: ``"model"``,
        ``"xm430?play_deg=0.8"``).
    counts_per_rev : int, optional
        With a pseudo-Wiener plant: the encoder's resolution (default 65536).
        A twin reports its output encoder's.
    noise : float
        Encoder noise standard deviation, rad (before quantisation); on a twin,
        its output encoder's noise (noise / resolution counts), drawn by the
        C firmware's own generator.
    seed : int
        Seed of the noise and of the injected faults.
    flip_tx, flip_rx : float
        Probability per byte that one bit is flipped, in the replies the
        firmware sends and in the requests it receives.
    drop : float
        Probability that a reply is not sent.
    mute_after : int, optional
        Send nothing after this many frames (a device that stops answering).
    restart_after : int, optional
        Restart after this many accepted requests (new boot id, clock from 0,
        torque off).
    clock_start_us : int
        The firmware's microsecond clock at start (near 2**32 to test the wrap).
    boot_id : int, optional
        Boot id of the first power-up (default from the clock).
    trace : path, optional
        File receiving every frame the firmware sends, before any corruption.
    link : path, optional
        A symlink to the pseudo-terminal at a stable name.
    """

    servo: Servo | str = DEFAULT_SERVO
    counts_per_rev: int | None = None
    noise: float = 0.0
    seed: int = 0
    flip_tx: float = 0.0
    flip_rx: float = 0.0
    drop: float = 0.0
    mute_after: int | None = None
    restart_after: int | None = None
    clock_start_us: int = 0
    boot_id: int | None = None
    trace: str | os.PathLike[str] | None = None
    link: str | os.PathLike[str] | None = None

    def __post_init__(self) -> None:
        servo = self.servo if isinstance(self.servo, Servo) else parse_servo(self.servo)
        object.__setattr__(self, "servo", servo)
        m = servo.model
        if m is not None and (m.na > 8 or m.nb > 8 or m.delay > 32):
            raise ConfigError(
                f"the firmware's motor takes na <= 8, nb <= 8, delay <= 32; got {m.na}, {m.nb}, {m.delay}"
            )
        if servo.twin is not None:
            if self.counts_per_rev is not None:
                raise ConfigError(
                    f"counts_per_rev (={self.counts_per_rev!r}) sets the pseudo-Wiener plant's encoder; "
                    f"the twin {servo.name!r} has its own (load_encoder_cpr, motor_encoder_cpr)"
                )
            cpr = servo.twin.output_counts_per_rev
            if cpr != int(cpr) or not 16 <= cpr <= 2**24:
                raise ConfigError(
                    f"the twin's output encoder has {cpr:g} counts per output turn: the bench protocol needs a "
                    "whole number in 16..16777216"
                )
        else:
            validation.integer(
                "counts_per_rev", 65536 if self.counts_per_rev is None else self.counts_per_rev, minimum=16
            )
        validation.non_negative("noise", self.noise)
        validation.integer("seed", self.seed, minimum=0)
        for name in ("flip_tx", "flip_rx", "drop"):
            validation.in_unit_interval(name, getattr(self, name), open_low=False, open_high=False)
        for name in ("mute_after", "restart_after"):
            if getattr(self, name) is not None:
                validation.integer(name, getattr(self, name), minimum=0)
        validation.integer("clock_start_us", self.clock_start_us, minimum=0)
        if self.clock_start_us >= 2**32:
            raise ConfigError(f"clock_start_us (={self.clock_start_us}) must be < 2**32")
        if self.boot_id is not None and not 0 < self.boot_id < 65536:
            raise ConfigError(f"boot_id (={self.boot_id}) must lie in 1..65535")

    @property
    def counts_per_turn(self) -> int:
        """Encoder counts per output turn the firmware reports."""
        servo = self.servo
        assert isinstance(servo, Servo)
        if servo.twin is not None:
            return int(servo.twin.output_counts_per_rev)
        return 65536 if self.counts_per_rev is None else self.counts_per_rev

    def servo_arguments(self) -> list[str]:
        """The firmware's arguments that say which servo is behind its HAL."""
        servo = self.servo
        assert isinstance(servo, Servo)
        if servo.twin is None:
            m = servo.model
            assert m is not None
            return [
                "--a", ",".join(repr(float(v)) for v in m.a), "--b", ",".join(repr(float(v)) for v in m.b),
                "--delay", str(m.delay), "--m2", repr(m.m2), "--c1", repr(m.c1), "--c2", repr(m.c2),
                "--cpr", str(self.counts_per_turn), "--noise", repr(self.noise),
            ]  # fmt: skip
        params = servo.twin
        if self.noise:
            counts = self.noise / (2.0 * math.pi / params.output_counts_per_rev)
            params = params.replace(**{f"{params.output_encoder}_encoder_noise_counts": counts})
        phys, fw = params.pack()
        return [
            "--twin-phys",
            ",".join(repr(float(v)) for v in phys),
            "--twin-fw",
            ",".join(repr(float(v)) for v in fw),
            "--twin-output",
            params.output_encoder,
        ]

    def arguments(self) -> list[str]:
        """Command-line arguments of the firmware process."""
        args = [
            *self.servo_arguments(), "--seed", str(self.seed),
            "--flip-tx", repr(self.flip_tx), "--flip-rx", repr(self.flip_rx), "--drop", repr(self.drop),
            "--clock-start", str(self.clock_start_us),
        ]  # fmt: skip
        for flag, value in (("--mute-after", self.mute_after), ("--restart-after", self.restart_after)):
            if value is not None:
                args += [flag, str(value)]
        if self.boot_id is not None:
            args += ["--boot-id", f"{self.boot_id:04x}"]
        if self.trace is not None:
            args += ["--trace", str(self.trace)]
        if self.link is not None:
            args += ["--link", str(self.link)]
        return args


class FirmwareEmulator:
    """The compiled firmware running as a process on a pseudo-terminal.

    Parameters
    ----------
    options : FirmwareOptions, optional
        Plant and fault injection.

    Attributes
    ----------
    port : str
        The pseudo-terminal (or the link) to open.
    boot_id : int
        Boot id the firmware announced.
    """

    def __init__(self, options: FirmwareOptions | None = None) -> None:
        self.options = options if options is not None else FirmwareOptions()
        self.process: subprocess.Popen[bytes] | None = None
        self.port = ""
        self.boot_id = 0
        self._err: list[str] = []  # the firmware's stderr lines so far, read by a thread as they come
        self._seen = 0  # how many of them events() has handed out
        self._reader: threading.Thread | None = None

    @property
    def url(self) -> str:
        """The driver URL of the emulated servo."""
        return f"serial://{self.port}"

    def start(self) -> FirmwareEmulator:
        """Build (first time only) and start the firmware; returns once it serves its port."""
        binary = firmware_binary()
        self.process = subprocess.Popen(
            [str(binary), *self.options.arguments()], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            start_new_session=True,  # Ctrl-C in the terminal reaches the Python side, which stops it cleanly
        )  # fmt: skip
        make_realtime(self.process.pid)  # the firmware's clock first, where permitted (servoid.drivers.realtime)
        lines = self._first_lines(2)
        if len(lines) < 2 or not lines[0].startswith("port ") or not lines[1].startswith("boot "):
            err = self.stop()
            raise DriverError(f"the firmware did not start ({' | '.join(lines)}): {err}")
        self.port = lines[0].split(" ", 1)[1]
        self.boot_id = int(lines[1].split(" ", 1)[1], 16)
        # a thread drains stderr as the firmware writes it: a full pipe would block the firmware
        self._reader = threading.Thread(target=self._drain, args=(self.process.stderr,), daemon=True)
        self._reader.start()
        return self

    def _drain(self, stream: IO[bytes]) -> None:
        for line in stream:
            self._err.append(line.decode(errors="replace").rstrip("\n"))

    def events(self) -> list[str]:
        """The firmware's new lines on stderr: the torque going off, the watchdog acting (with the monotonic time)."""
        lines = self._err[self._seen :]
        self._seen += len(lines)
        return lines

    def _first_lines(self, count: int) -> list[str]:
        # raw reads with a deadline: a buffered readline() would swallow the second line
        assert self.process is not None and self.process.stdout is not None
        fd = self.process.stdout.fileno()
        data = b""
        deadline = time.monotonic() + START_TIMEOUT_S
        while data.count(b"\n") < count:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([fd], [], [], remaining)[0]:
                break
            chunk = os.read(fd, 4096)
            if not chunk:
                break
            data += chunk
        return [line.strip() for line in data.decode(errors="replace").splitlines()[:count]]

    def stop(self) -> str:
        """Stop the firmware (SIGTERM, then SIGKILL); return what it printed on stderr."""
        proc, self.process = self.process, None
        if proc is None:
            return ""
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if self._reader is not None:
            self._reader.join(timeout=5)
            self._reader = None
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()
        return "\n".join(self._err).strip()

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def __enter__(self) -> FirmwareEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def __del__(self) -> None:
        if getattr(self, "process", None) is not None:
            self.stop()
