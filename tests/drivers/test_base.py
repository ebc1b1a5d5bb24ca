"""The base class's own logic, on a minimal driver that records what reaches its primitives.

These test what the base promises every driver (clamping before sending, unit
conversion, idempotent close with torque off, error wrapping, clock unwrapping);
each real driver is then tested against its emulator by the contract tests.
"""

import math

import numpy as np
import pytest

from servoid.drivers import Driver, Limits, Reading, UnitConversion, parse_url, register
from servoid.drivers.registry import driver_from_url
from servoid.errors import ConfigError, DriverError, DriverTimeout, MissingDependency


class Recorder(Driver):
    scheme = "recorder"
    clock_wrap_s = 10.0

    def __init__(self, *, fail_with: BaseException | None = None, clock: list[float] | None = None, **kw):
        super().__init__(**kw)
        self.sent: list[float] = []
        self.torque_calls: list[bool] = []
        self.fail_with = fail_with
        self.clock = list(clock or [])
        self.closed = 0

    def _open(self):
        pass

    def _close(self):
        self.closed += 1

    def _set_torque(self, enabled):
        self.torque_calls.append(enabled)

    def _exchange(self, command, slot=None):
        if self.fail_with is not None:
            raise self.fail_with
        self.sent.append(command)
        return Reading(position=2 * command, device_time=self.clock.pop(0) if self.clock else None)


def test_commands_outside_the_limits_are_clamped_counted_and_never_sent():
    d = Recorder(limits=Limits(minimum=-1.0, maximum=1.0, max_step=0.5))
    with d:
        d.enable()
        ms = [d.exchange(u) for u in (0.2, 5.0, 5.0, -5.0, 0.0)]
    assert [m.command for m in ms] == [0.2, 0.7, 1.0, 0.5, 0.0]
    assert [m.clamped for m in ms] == [False, True, True, True, False]
    assert d.sent == [0.2, 0.7, 1.0, 0.5, 0.0]
    assert max(abs(v) for v in d.sent) <= 1.0 and d.stats.clamped == 3 and d.stats.exchanges == 5


def test_commands_are_rounded_to_the_device_step_inside_the_limits_and_reported_as_sent():
    counts = UnitConversion("rad", scale=2 * math.pi / 4096, offset=2048)
    d = Recorder(position_unit=counts, command_unit=counts, limits=Limits(minimum=-0.3, maximum=0.5))
    d.command_step = 1.0
    with d:
        d.enable()
        ms = [d.exchange(u) for u in (0.1, 0.4999, -1.0)]
    # 0.1 rad is 65.2 counts; 0.4999 rad is 325.9 counts, whose nearest count (326 = 0.5001 rad)
    # lies past the limit, and -1 rad is clamped to -0.3 rad = -195.6 counts (-196 = -0.3007 rad):
    # the count on the inside is sent instead
    assert d.sent == [2048 + 65, 2048 + 325, 2048 - 195]
    assert [m.command for m in ms] == pytest.approx([counts.to_user(v) for v in d.sent], abs=1e-15)
    assert [m.clamped for m in ms] == [False, False, True]  # rounding is not clamping


def test_units_convert_both_ways():
    counts = UnitConversion("rad", scale=2 * math.pi / 4096, offset=2048)
    d = Recorder(position_unit=counts, command_unit=counts)
    with d:
        m = d.exchange(math.pi / 2)
    assert d.sent == [pytest.approx(3072.0)]  # pi/2 rad is a quarter turn above the centre
    assert m.position == pytest.approx((2 * 3072.0 - 2048) * 2 * math.pi / 4096)


def test_close_is_idempotent_and_switches_torque_off():
    d = Recorder()
    d.open()
    d.enable()
    d.close()
    d.close()
    assert d.torque_calls == [True, False] and d.closed == 1 and not d.is_open
    with pytest.raises(DriverError, match="is not open"):
        d.exchange(0.0)


def test_errors_are_wrapped_into_servoid_errors():
    with Recorder(fail_with=TimeoutError("read timed out")) as d:
        with pytest.raises(DriverTimeout, match="no answer in time") as info:
            d.exchange(0.0)
        assert isinstance(info.value, TimeoutError) and isinstance(info.value.__cause__, TimeoutError)
    with Recorder(fail_with=OSError(5, "Input/output error")) as d:
        with pytest.raises(DriverError, match="OSError"):
            d.exchange(0.0)
        assert d.stats.errors == 1
    with Recorder() as d, pytest.raises(ConfigError, match="must be finite"):
        d.exchange(float("nan"))


def test_device_clock_is_unwrapped():
    with Recorder(clock=[9.0, 9.9, 0.3, 5.0, 9.8, 0.1]) as d:
        times = [d.exchange(0.0).device_time for _ in range(6)]
    assert times == pytest.approx([9.0, 9.9, 10.3, 15.0, 19.8, 20.1])


def test_urls_and_options():
    register("recorder", f"{__name__}:Recorder")
    url = parse_url("recorder:///dev/x?max=2&max_step=0.1")
    assert (url.scheme, url.path, dict(url.options)) == ("recorder", "/dev/x", {"max": "2", "max_step": "0.1"})
    d = driver_from_url("recorder://?min=-2&max=2")
    assert d.limits == Limits(minimum=-2.0, maximum=2.0)
    with pytest.raises(ConfigError, match="unknown option.*bogus.*accepts .*max_step"):
        driver_from_url("recorder://?bogus=1")
    with pytest.raises(ConfigError, match="option max='x' is invalid"):
        driver_from_url("recorder://?max=x")
    with pytest.raises(ConfigError, match="unknown driver scheme 'nope'"):
        parse_url("nope://x")
    with pytest.raises(ConfigError, match="must look like scheme://"):
        parse_url("/dev/ttyUSB0")
    with pytest.raises(ConfigError, match="given twice"):
        parse_url("recorder://?max=1&max=2")


def test_a_missing_vendor_library_names_the_package(tmp_path, monkeypatch):
    (tmp_path / "needs_pyserial_driver.py").write_text("import serial\nclass X: pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(__import__("sys").modules, "serial", None)  # as if pyserial were not installed
    register("needsserial", "needs_pyserial_driver:X")
    with pytest.raises(MissingDependency, match=r"needs the package 'pyserial': pip install 'servoid\[serial\]'"):
        driver_from_url("needsserial://")


def test_limits_validate():
    with pytest.raises(ConfigError, match="minimum .* must be < maximum"):
        Limits(minimum=1.0, maximum=0.0)
    with pytest.raises(ConfigError, match="max_step"):
        Limits(max_step=0.0)


def test_amplitude_band_and_range_clamp_together():
    lim = Limits(minimum=-1.0, maximum=0.5, amplitude=0.3, centre=0.4)
    assert (lim.low, lim.high) == (pytest.approx(0.1), 0.5)
    with Recorder(limits=lim) as d:
        d.enable()
        assert [d.exchange(u).command for u in (0.0, 0.3, 2.0)] == [pytest.approx(0.1), 0.3, 0.5]
    assert min(d.sent) >= 0.1 - 1e-12 and d.stats.clamped == 2
    with pytest.raises(ConfigError, match="outside"):
        Limits(minimum=0.0, maximum=1.0, centre=3.0, amplitude=0.5)
    assert driver_from_url("recorder://?amplitude=0.2&centre=1").limits.high == pytest.approx(1.2)


def test_a_measured_position_beyond_the_guard_stops_with_the_torque_off():
    from servoid.errors import PositionOutOfRange

    d = Recorder(limits=Limits(minimum=-1.0, maximum=1.0, guard=0.5))
    with d:
        d.enable()
        d.exchange(0.7)  # measured 1.4: inside the guard
        with pytest.raises(PositionOutOfRange, match="outside .* guard=0.5; torque switched off"):
            d.exchange(0.8)  # measured 1.6
        assert not d.torque_enabled and d.torque_calls == [True, False]


def test_the_sample_period_and_slot_reach_the_driver():
    class Periodic(Recorder):
        def _set_period(self, period_s):
            self.period = period_s

        def _exchange(self, command, slot):
            self.slots.append(slot)
            return super()._exchange(command, slot)

    d = Periodic()
    d.slots = []
    with d:
        d.set_sample_period(0.002)
        d.exchange(0.0)
        d.exchange(0.0, slot=7)
        with pytest.raises(ConfigError, match="slot"):
            d.exchange(0.0, slot=-1)
    assert d.period == 0.002 and d.sample_period_s == 0.002 and d.slots == [None, 7]
    with Recorder() as r, pytest.raises(ConfigError, match="period_s"):
        r.set_sample_period(-1.0)


@pytest.mark.parametrize("command_step", [None, 0.004])
def test_after_lost_requests_and_replies_no_step_the_servo_receives_exceeds_max_step(command_step):
    # The servo applies a command whose reply is lost, and not one whose request is lost: the base
    # cannot tell which, so the next command must lie within max_step of both.
    class Lossy(Recorder):
        def __init__(self, **kw):
            super().__init__(**kw)
            self.rng = np.random.default_rng(11)
            self.applied: list[float] = []

        def _exchange(self, command, slot=None):
            fate = self.rng.random()
            if fate < 0.2:
                raise DriverTimeout("request lost")
            self.applied.append(command)
            if fate < 0.4:
                raise DriverTimeout("reply lost")
            return Reading(position=command)

    max_step = 0.01
    d = Lossy(limits=Limits(minimum=-1.0, maximum=1.0, max_step=max_step))
    d.command_step = command_step
    u = np.random.default_rng(3).uniform(-0.5, 0.5, 3000)
    with d:
        d.enable()
        for v in u:
            try:
                d.exchange(v)
            except DriverTimeout:
                pass
            assert d.last_command is not None and d.possibly_held is not None
    steps = np.abs(np.diff(d.applied))
    assert steps.max() <= max_step * (1 + 1e-9), f"a step of {steps.max():.4g} reached the servo"
    assert steps.max() >= max_step - (command_step or 0.0) - 1e-12  # the limit bound, nothing froze
    if command_step is not None:
        np.testing.assert_allclose(
            np.asarray(d.applied) / command_step, np.round(np.asarray(d.applied) / command_step), atol=1e-9
        )


class Resting(Recorder):
    """A servo that rests at ``rest`` when the torque comes on and can be read without commanding."""

    def __init__(self, rest: float, **kw):
        super().__init__(**kw)
        self.rest = rest

    def _read(self):
        return Reading(position=self.rest)


@pytest.mark.parametrize("rest", [0.0, 0.93, 2.0])
def test_the_first_commands_after_enable_lie_within_max_step_of_where_the_servo_rests(rest):
    limits = Limits(minimum=-3.0, maximum=3.0, centre=1.0, amplitude=0.1, max_step=0.05)
    d = Resting(rest, limits=limits)
    with d:
        d.enable()
        for u in np.random.default_rng(3).uniform(0.9, 1.1, 60):
            d.exchange(u)
    steps = np.abs(np.diff([rest, *d.sent]))
    assert steps.max() <= 0.05 + 1e-12  # from the rest position on, never a larger step
    assert 0.9 <= d.sent[-1] <= 1.1  # and the servo reaches the band
    assert all(-3.0 <= v <= 3.0 for v in d.sent)


def test_a_driver_that_cannot_read_keeps_the_band_as_its_only_bound_for_the_first_command():
    d = Recorder(limits=Limits(minimum=-3.0, maximum=3.0, centre=1.0, amplitude=0.1, max_step=0.05))
    with d:
        d.enable()
        d.exchange(1.05)
    assert d.sent == [1.05]
