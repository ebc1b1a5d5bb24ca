"""The serial bench servo: the C firmware's plant and protocol, and the pyserial driver's checks.

Everything here runs the compiled reference firmware (built once per machine
into the cache) as its own process on a pseudo-terminal.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import serial

from servoid.drivers import driver_from_url
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.drivers.serial import build
from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions
from servoid.drivers.serial.protocol import FrameSplitter, check, crc16, encode, parse_reply
from servoid.drivers.servos import Servo
from servoid.errors import ConfigError, DeviceFault, DriverError, MissingDependency, ProtocolError
from servoid.ident import PAPER_PLANT, BacklashModel, simulate
from servoid.recording import read_recording
from servoid.session import SessionConfig, run_session


@pytest.fixture(scope="module")
def firmware():
    return build.firmware_binary()


# ---- the plant in C ----------------------------------------------------------------------
@pytest.mark.parametrize(
    "model",
    [MODEL_PLANT, PAPER_PLANT, BacklashModel(a=(-1.2, 0.5, -0.06), b=(0.2, 0.15), delay=3, m2=0.7, c1=0.1, c2=0.05)],
    ids=["bench", "paper", "na3-nb1-d3"],
)
def test_the_firmware_plant_matches_simulate_sample_by_sample(firmware, model):
    u = np.random.default_rng(1).uniform(-2.0, 2.0, 3000)
    args = FirmwareOptions(servo=Servo("custom", None, model, "rad", 0.2)).arguments()
    done = subprocess.run([str(firmware), "--plant-only", *args], input="\n".join(repr(float(v)) for v in u) + "\n",
                          capture_output=True, text=True, check=True)  # fmt: skip
    y_c = np.array(done.stdout.split(), dtype=float)
    np.testing.assert_allclose(y_c, simulate(model, u).y, rtol=0, atol=1e-12)


# ---- framing -----------------------------------------------------------------------------
def test_crc_is_ccitt_false_and_every_single_bit_flip_is_rejected():
    assert crc16(b"123456789") == 0x29B1  # the CRC-16/CCITT-FALSE check value
    frame = encode("65535 P 3fa2 4294967295 4294967295 -2147483648")[:-1]
    assert parse_reply(frame).ints() == (4294967295, 4294967295, -2147483648)
    for i in range(len(frame)):
        for bit in range(8):
            bad = bytearray(frame)
            bad[i] ^= 1 << bit
            assert check(bytes(bad)) is None, (i, bit)
    rng = np.random.default_rng(3)
    for _ in range(20_000):  # two or three flipped bits: CRC-16/CCITT catches them all in frames this short
        bad = bytearray(frame)
        for pos in rng.choice(len(frame) * 8, size=rng.integers(2, 4), replace=False):
            bad[pos // 8] ^= 1 << (pos % 8)
        assert check(bytes(bad)) is None


@pytest.mark.parametrize("line", [b"", b"1 P 3fa2 1 2*0000", b"1 Z 3fa2*" + b"%04X" % crc16(b"1 Z 3fa2"),
                                  encode("1 P 3fa2 1 2")[:-1], encode("1 P 3fa2 x 2 3")[:-1],
                                  encode("1 K 3f")[:-1], encode("70000 K 3fa2")[:-1]])  # fmt: skip
def test_malformed_replies_are_protocol_errors(line):
    with pytest.raises(ProtocolError):
        parse_reply(line)


def test_frames_are_split_from_any_chunking_and_garbage_is_dropped():
    stream = encode("1 K 0001") + b"x" * 200 + b"\n" + encode("2 K 0001")
    for size in (1, 3, 7, len(stream)):
        splitter = FrameSplitter()
        lines = [line for i in range(0, len(stream), size) for line in splitter.feed(stream[i : i + size])]
        good = [parse_reply(line).seq for line in lines if check(line) is not None]
        assert good == [1, 2]


# ---- the firmware over its pty -------------------------------------------------------------
def raw_exchange(port: serial.Serial, body: str) -> bytes:
    port.write(encode(body))
    deadline = time.monotonic() + 1.0
    data = b""
    while not data.endswith(b"\n") and time.monotonic() < deadline:
        data += port.read(port.in_waiting or 1)
    return data.rstrip(b"\n")


def test_the_firmware_answers_requests_and_refuses_bad_ones():
    with FirmwareEmulator(FirmwareOptions(boot_id=0x3FA2, servo="model")) as emu:
        port = serial.Serial(emu.port, 1_000_000, timeout=0.2)
        assert parse_reply(raw_exchange(port, "1 H")).fields == ("1", "65536", "servoid-bench/1.0")
        assert parse_reply(raw_exchange(port, "2 Z")).fields == ("1",)  # unknown verb
        assert parse_reply(raw_exchange(port, "3 S 5")).fields == ("2",)  # torque off
        assert parse_reply(raw_exchange(port, "4 E 1")).kind == "K"
        assert parse_reply(raw_exchange(port, "5 S 99999999")).fields == ("3",)  # beyond the travel
        assert parse_reply(raw_exchange(port, "6 R 1")).fields == ("4",)  # streaming needs a period
        assert parse_reply(raw_exchange(port, "7 S 10 7")).kind == "P"
        assert parse_reply(raw_exchange(port, "8 S 10 7")).fields == ("5",)  # the same slot twice
        port.write(b"9 Q*0000\n")  # bad CRC: dropped, counted
        reply = parse_reply(raw_exchange(port, "10 Q"))
        torque, period, rx_ok, rx_bad, tx = reply.ints()
        assert (reply.seq, reply.boot, torque, rx_bad) == (10, 0x3FA2, 1, 1) and rx_ok == 9
        port.close()


def test_refusals_become_driver_errors_and_units_follow_the_encoder():
    with FirmwareEmulator(FirmwareOptions(counts_per_rev=4096, servo="model")) as emu:
        with driver_from_url(f"{emu.url}?unit=counts") as servo:
            with pytest.raises(DeviceFault, match="torque is off"):
                servo.exchange(10)
            servo.enable()
            servo.exchange(100)
            m = servo.exchange(100)
            assert m.position == round(m.position) and servo.identity["counts_per_rev"] == 4096
        with driver_from_url(emu.url) as servo:
            assert servo.position_unit.unit == "rad"
            assert servo.position_unit.scale == pytest.approx(2 * np.pi / 4096)
            servo.enable()
            with pytest.raises(DriverError, match="out of range"):
                servo.exchange(200.0)  # 16 turns of travel (100.5 rad): 200 rad is beyond
    with pytest.raises(ConfigError, match="unit='deg' is invalid"):
        driver_from_url("serial:///dev/null?unit=deg")
    with pytest.raises(DriverError, match="cannot open"):
        driver_from_url("serial:///dev/no-such-port").open()


def test_streaming_is_device_timed():
    with FirmwareEmulator() as emu, driver_from_url(emu.url) as servo:
        servo.set_sample_period(0.002)
        servo.enable()
        servo.start_stream()
        times = [servo.read_stream().device_time for _ in range(40)]
        servo.stop_stream()
        assert servo.exchange(0.0).position == pytest.approx(0.0, abs=1e-3)  # replies still pair up after it
    steps = np.diff(times)
    assert np.median(steps) == pytest.approx(0.002, abs=2e-6)  # the device's clock, not the host's
    assert np.all(steps > 0)


def test_the_device_clock_is_unwrapped_through_the_u32_wrap():
    start = 2**32 - 150_000  # 0.15 s before the microsecond counter wraps
    with FirmwareEmulator(FirmwareOptions(clock_start_us=start)) as emu, driver_from_url(emu.url) as servo:
        servo.enable()
        times = []
        deadline = time.monotonic() + 0.4
        while time.monotonic() < deadline:
            times.append(servo.exchange(0.0).device_time)
            time.sleep(0.005)
    assert times[0] < 2**32 * 1e-6 < times[-1]
    assert np.all(np.diff(times) > 0)


def test_a_missing_compiler_is_named(monkeypatch):
    monkeypatch.setattr(build.shutil, "which", lambda name: None)
    with pytest.raises(MissingDependency, match="C compiler"):
        build.firmware_binary()


def test_a_set_point_lost_on_its_way_is_never_taken_as_applied():
    # bits flipped on the way to the firmware: a set point whose CRC fails is dropped, unanswered; whether
    # the request or the reply was lost is unknown, so the sample and the guard window after it are not used
    u = np.random.default_rng(3).uniform(-0.2, 0.2, 800)
    with FirmwareEmulator(FirmwareOptions(servo="model", flip_rx=0.002, seed=3)) as emu:
        with driver_from_url(f"{emu.url}?timeout=0.01") as servo:
            result = run_session(servo, u, SessionConfig(period_s=0.002, give_up_after_s=2.0))
            dropped = servo.status()["rx_bad"]
    timeouts = np.flatnonzero(result.status == "timeout")
    assert dropped > 0 and timeouts.size > 0 and result.config.guard_samples == 10
    for k in timeouts:
        assert not result.valid[k : k + 11].any(), f"a sample within 10 after the lost set point {k} was used"
    assert result.valid.sum() > 100  # and the run still identifies from what is left


def test_a_killed_host_leaves_its_recording_readable_and_the_watchdog_drops_the_torque(tmp_path):
    path = tmp_path / "rec.csv"
    with FirmwareEmulator() as emu:
        script = textwrap.dedent(f"""
            import numpy as np
            from servoid.drivers import driver_from_url
            from servoid.session import SessionConfig, run_session
            u = np.random.default_rng(0).uniform(-0.2, 0.2, 100_000)
            with driver_from_url("{emu.url}?watchdog=0.2") as servo:
                run_session(servo, u, SessionConfig(period_s=0.002), recording="{path}")
        """)  # fmt: skip
        host = subprocess.Popen([sys.executable, "-c", script])
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and (not path.exists() or path.stat().st_size < 20_000):
            time.sleep(0.05)
        os.kill(host.pid, signal.SIGKILL)
        host.wait()
        rec = read_recording(path)
        assert len(rec) > 100 and np.isfinite(rec.y[: len(rec) // 2]).any()
        time.sleep(0.4)  # > the watchdog
        with driver_from_url(emu.url) as servo:
            assert servo.status()["torque"] == 0


def test_a_set_point_after_a_host_stall_past_the_watchdog_is_refused_naming_the_silence():
    with FirmwareEmulator() as emu, driver_from_url(f"{emu.url}?watchdog=0.1") as servo:
        servo.set_sample_period(0.01)
        servo.enable()
        servo.exchange(0.0)
        time.sleep(0.3)  # the host stalls: the firmware's watchdog switches the torque off
        with pytest.raises(DeviceFault, match=r"the torque is off: the servo's watchdog switched it off, no request "
                                              r"for [\d.]+ s before this one \(watchdog 0\.1 s: the host stalled\)"):  # fmt: skip
            servo.exchange(0.0)
