"""The C firmware's twin against the Python twin: the same preset and set points give the same readings, bit for bit.

The bench firmware's loop (``firmware/loop.c``, the port of
``servoid/drivers/twin/firmware.py``) and the host build's physics
(``firmware/host/twin_sim.c``, the port of ``kernel.py``) compute with the
same numbers in the same order as the Python twin; ``servoid-bench-fw
--twin-only`` steps one host period per set point, as
:class:`~servoid.drivers.twin.TwinPlant` does, and prints the drive's
registers at each set point's arrival. Encoder noise is the one thing that
differs: C draws it from its own seeded generator, so with noise the two
agree in distribution only; the presets have none.
"""

from __future__ import annotations

import re
import subprocess
import time

import numpy as np
import pytest

from servoid.drivers.serial import build
from servoid.drivers.serial.emulator import FirmwareOptions
from servoid.drivers.twin import Twin, TwinPlant, preset
from servoid.drivers.twin import _layout as layout
from servoid.errors import ConfigError

FIELDS = ("motor counts", "load counts", "velocity", "position estimate", "current", "duty", "set point", "enabled",
          "fault")  # fmt: skip


@pytest.fixture(scope="module")
def firmware():
    return build.firmware_binary()


def c_twin(firmware, params, u: np.ndarray, period_s: float) -> np.ndarray:
    """The C twin's registers at each set point's arrival (one row per set point)."""
    phys, fw = params.pack()
    args = ["--twin-phys", ",".join(map(repr, map(float, phys))), "--twin-fw", ",".join(map(repr, map(float, fw))),
            "--twin-output", params.output_encoder, "--period-us", repr(period_s * 1e6)]  # fmt: skip
    done = subprocess.run([str(firmware), "--twin-only", *args], input="".join(f"{v!r}\n" for v in map(float, u)),
                          capture_output=True, text=True, check=True)  # fmt: skip
    return np.array([line.split() for line in done.stdout.splitlines()], dtype=float)


def python_twin(params, u: np.ndarray, period_s: float) -> np.ndarray:
    plant = TwinPlant(Twin(params), period_s)
    rows = []
    for v in u:
        r = plant.twin.read()
        rows.append([r.motor_counts or 0, r.load_counts or 0, r.velocity_rad_s, r.position_estimate_rad, r.current_a,
                     r.duty, r.setpoint_rad, r.enabled, r.fault is not None])  # fmt: skip
        plant.step(float(v))
    return np.array(rows, dtype=float)


def test_the_c_layout_is_the_python_layout():
    text = (build.FIRMWARE_DIR / "twin_layout.h").read_text()
    defines = {name: int(value) for name, value in re.findall(r"#define TW_(\w+) (\d+)", text)}
    python = {n: getattr(layout, n) for n in dir(layout) if n.split("_")[0] in ("P", "F", "M", "FW", "ENC", "FAULT")}
    assert defines == python


@pytest.mark.parametrize(
    ("name", "overrides", "amplitude", "period_s"),
    [
        ("xm430", {}, 0.1, 0.005),
        ("sts3215", {"pos_i": 5}, 0.05, 0.004),
        ("cia402", {}, 0.1, 0.002),
        ("odrive", {}, 0.3, 0.005),  # faults on overspeed along the way: the fault is compared too
        ("xm430", {"load_mass_kg": 0.3, "load_arm_m": 0.05}, 0.5, 0.003),  # gravity
        ("cia402", {"loop_encoder": "load"}, 0.1, 0.002),
    ],
    ids=["xm430", "sts3215+I", "cia402", "odrive-overspeed", "xm430-pendulum", "cia402-load-loop"],
)
def test_the_c_twin_reads_what_the_python_twin_reads_sample_for_sample(firmware, name, overrides, amplitude, period_s):
    params = preset(name, **overrides)
    u = np.random.default_rng(7).uniform(-amplitude, amplitude, 400)
    c, py = c_twin(firmware, params, u, period_s), python_twin(params, u, period_s)
    for i, field in enumerate(FIELDS):
        differ = np.flatnonzero(c[:, i] != py[:, i])
        assert differ.size == 0, (
            f"{field} differs first at sample {differ[0]}: C {c[differ[0], i]!r}, Python {py[differ[0], i]!r}"
        )
    assert np.ptp(py[:, 1]) > 10  # it moved
    if name == "odrive":
        assert py[-1, 8] == 1 and py[-1, 7] == 0  # the overspeed really happened, in both


def test_the_serial_emulator_passes_the_twin_and_refuses_what_the_protocol_cannot_carry():
    options = FirmwareOptions(servo="cia402?play_arcmin=3")
    args = options.servo_arguments()
    assert args[0] == "--twin-phys" and args[-1] == "load" and options.counts_per_turn == 2**20
    assert FirmwareOptions(servo="model").counts_per_turn == 65536
    with pytest.raises(ConfigError, match="counts_per_rev .* the twin 'xm430' has its own"):
        FirmwareOptions(counts_per_rev=4096)
    with pytest.raises(ConfigError, match="353.5 counts per output turn.*whole number"):
        FirmwareOptions(servo="xm430?output_encoder=motor&motor_encoder_cpr=1")


def test_a_twin_that_faults_behind_the_firmware_is_a_device_fault_never_a_coasting_servo():
    from servoid.drivers import driver_from_url
    from servoid.drivers.serial.emulator import FirmwareEmulator
    from servoid.errors import DeviceFault

    # the ODrive's default gains: quick reversals of 1.6 rad spin its motor past 1.2 x vel_limit
    with FirmwareEmulator(FirmwareOptions(servo="odrive")) as emu, driver_from_url(emu.url) as servo:
        servo.set_sample_period(0.005)
        servo.enable()
        with pytest.raises(DeviceFault, match="turned itself off"):
            for v in np.random.default_rng(1).uniform(-1.6, 1.6, 400):
                servo.exchange(float(v))
        assert servo.status()["torque"] == 0
        servo.enable()  # re-armed
        servo.exchange(0.0)
        time.sleep(0.1)
        events = emu.events()  # the firmware reports the torque-off, as it does the watchdog's (hal_event)
    assert any("motor fault: the output stage turned itself off" in line for line in events), events
    assert any("servoid-bench-fw: torque off" in line for line in events), events
