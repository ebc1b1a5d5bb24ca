"""The simulated servo behind the driver interface, ``sim://``: a physical twin, or the estimator's own plant.

URL::

    sim://xm430?play_deg=0.8&snr=40&latency=0.0002&drop=0.01&seed=1   a Dynamixel XM430 twin, its play overridden
    sim://?clock=virtual                                              the default servo (xm430)
    sim://model?snr=40                                                the pseudo-Wiener bench plant (exact tests)
    sim://gear?snr=40&clock=virtual&drift=1.5&drift_samples=200000    a wearing gear

The URL's host names the servo (:mod:`servoid.drivers.servos`: ``xm430``,
``sts3215``, ``cia402``, ``odrive``, ``model``, ``paper``, ``gear``;
default ``xm430``); options that are not the driver's own override a
twin's parameters by name (``play_deg=0.8``, ``motor_coulomb_nm=...``).

It is a driver like any other (same registry, same contract tests, same
failure behaviour) with its time taken from an injected
:class:`~servoid.drivers.clock.Clock`: give it and the sampling session one
:class:`~servoid.drivers.clock.VirtualClock` and every run, including its
late, missed and timed-out samples, is reproducible on any machine.

The device side (:class:`SimDevice`) is kept apart from the driver side, as
on a real link: the device has a boot id and a clock that restart when it
restarts, drops replies, goes silent; the driver only sees replies (or their
absence) and detects the restart from the boot id. A twin that turns its
drive stage off by itself (the ODrive's overspeed) is reported as a
:class:`~servoid.errors.DeviceFault`, as a real drive's error is.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from servoid import readings_side, validation
from servoid.drivers import options as opt
from servoid.drivers.base import Driver, DriverURL, Option, Reading, UnitConversion
from servoid.drivers.clock import NS_PER_S, Clock, MonotonicClock, VirtualClock
from servoid.drivers.sampled import PlantSample, SampledPlant
from servoid.drivers.servos import DEFAULT_RATE_HZ, DEFAULT_SERVO, Servo, servo_names, twin_option_names
from servoid.drivers.servos import servo as make_servo
from servoid.drivers.twin import Twin, TwinParams, TwinPlant, TwinTruth
from servoid.errors import ConfigError, DeviceFault, DeviceRestarted, DriverError, DriverTimeout
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import simulate
from servoid.ident.models.wear import Wear

__all__ = ["SimDriver", "SimDevice", "reference_output_std"]


def reference_output_std(servo: Servo) -> float:
    """Standard deviation of the servo's output under its reference input (the base of ``snr``).

    For a pseudo-Wiener plant, its simulated output under a uniform input of
    its reference amplitude; for a twin, that input's own standard deviation
    (``amplitude / sqrt(3)``): a position servo's output follows its set
    point, and a twin's output depends on the host's rate, which is not
    known when the noise is set.
    """
    if servo.model is None:
        return servo.amplitude / math.sqrt(3.0)
    u = np.random.default_rng(0).uniform(-servo.amplitude, servo.amplitude, 20_000)
    return float(np.std(simulate(servo.model, u).y_clean))


class SimDevice:
    """The simulated servo on the far side of the link.

    Parameters
    ----------
    plant : SampledPlant
        Its physics.
    clock : Clock
        Time source; replies take ``latency`` (+ jitter) of it.
    latency_ns, jitter_ns : int
        Fixed reply delay, and the mean of an exponential extra delay.
    drop : float
        Probability that a reply is lost (the command still takes effect).
    mute_after : int or None
        Stop answering after this many exchanges (a cable pulled, a crash).
    restart_after : int or None
        Restart after this many exchanges: torque off, plant at rest, new boot id,
        device clock from zero.
    rng : numpy.random.Generator
        Source of drops and jitter.
    """

    def __init__(
        self,
        plant: SampledPlant,
        *,
        clock: Clock,
        latency_ns: int = 0,
        jitter_ns: int = 0,
        drop: float = 0.0,
        mute_after: int | None = None,
        restart_after: int | None = None,
        rng: np.random.Generator,
    ) -> None:
        self.plant = plant
        self.clock = clock
        self.latency_ns, self.jitter_ns = latency_ns, jitter_ns
        self.drop, self.mute_after, self.restart_after = drop, mute_after, restart_after
        self.rng = rng
        self.boot_id = 1
        self.boot_ns = clock.now_ns()
        self.exchanges = 0

    def request(self, command: float | None, periods: int | None = None) -> tuple[PlantSample, int] | None:
        """Serve one request: a command (or a read with None); None when no reply comes back.

        ``periods`` is the host's count of sample periods since its previous command.
        """
        self.exchanges += 1
        if self.mute_after is not None and self.exchanges > self.mute_after:
            return None
        if self.restart_after is not None and self.exchanges == self.restart_after + 1:
            self.plant.reset()
            self.boot_id += 1
            self.boot_ns = self.clock.now_ns()
        now = self.clock.now_ns()
        if command is not None and self.plant.enabled:
            sample = self.plant.command(command, now, periods=periods)
        else:
            sample = self.plant.read(now)
        delay = self.latency_ns
        if self.jitter_ns:
            delay += int(self.rng.exponential(self.jitter_ns))
        if self.drop and self.rng.random() < self.drop:
            return None
        self.clock.sleep_ns(delay)
        return sample, self.boot_id

    def device_time(self, sample: PlantSample) -> float:
        """The device's clock at a sample, seconds since its (last) boot."""
        return (sample.time_ns - self.boot_ns) / NS_PER_S


class SimDriver(Driver):
    """The simulated servo (``sim://``).

    Parameters
    ----------
    servo : str or Servo
        Which servo (:mod:`servoid.drivers.servos`): a twin preset (``xm430``,
        the default; ``sts3215``, ``cia402``, ``odrive``) or a pseudo-Wiener
        plant (``model``: :data:`~servoid.drivers.model_plant.MODEL_PLANT` in rad;
        ``paper``: the paper's Section 4 plant, unitless; ``gear``: the
        paper's plant with a new gear, ``c1 + c2 = 1``).
    twin_options : mapping, optional
        A twin's parameters overridden by name (``{"play_deg": "0.8"}``;
        text accepted); the URL's options that are not the driver's own.
    snr : float, optional
        Measurement noise as a signal-to-noise ratio: noise standard deviation
        = std of the output under the servo's reference input / ``snr``
        (:func:`reference_output_std`).
    noise : float, optional
        Measurement noise standard deviation, the servo's unit (instead of
        ``snr``). A twin's noise is its output encoder's, before quantisation
        (``encoder_noise_counts`` = noise / resolution): it enters the drive's
        loop as it does on a real servo.
    latency, jitter : float
        Reply delay and mean exponential extra delay, seconds.
    drop : float
        Probability that a reply is lost (a timeout).
    timeout : float
        How long to wait for a reply, seconds.
    mute_after, restart_after : int, optional
        Fault injection: go silent, or restart, after this many exchanges.
    seed : int
        Seed of the noise, drops and jitter.
    clock : Clock or {"real", "virtual"}, optional
        Time source; default the real clock. ``virtual`` (also a URL option)
        runs in simulated time: a session takes no wall time and repeats exactly.
    drift, drift_samples, drift_start, swap_at, swap_factor : optional
        Simulated wear (:class:`~servoid.ident.models.wear.Wear`): the dead zones
        ``c1`` and ``c2`` (a twin: its play) ramp by the factor ``drift`` over
        ``drift_samples`` samples from sample ``drift_start``, and are
        multiplied by ``swap_factor`` from sample ``swap_at`` on (a gear swap).
        Samples are the servo's own, so the wear follows time, not the host's requests.
    **kwargs
        Limits and units for :class:`~servoid.drivers.base.Driver`.
    """

    scheme: ClassVar[str] = "sim"
    carries_slots: ClassVar[bool] = True  # the simulated plant steps on the session's slots
    options: ClassVar[Mapping[str, Option]] = {
        "snr": Option(
            opt.number(low=0, low_open=True), "measurement noise as sqrt(var(y)/var(noise)) under the reference input"
        ),
        "noise": Option(opt.number(low=0), "measurement noise standard deviation (the servo's unit)"),
        "latency": Option(opt.number(low=0), "reply delay (s)"),
        "jitter": Option(opt.number(low=0), "mean exponential extra reply delay (s)"),
        "drop": Option(opt.number(low=0, high=1, what="a probability"), "probability that a reply is lost, in [0, 1]"),
        "timeout": Option(opt.number(low=0, low_open=True), "how long to wait for a reply (s, default 0.05)"),
        "mute_after": Option(opt.integer(), "stop answering after this many exchanges (fault injection)"),
        "restart_after": Option(opt.integer(), "restart after this many exchanges (fault injection)"),
        "seed": Option(opt.integer(), "seed of noise, drops and jitter (default 0)"),
        "clock": Option(
            opt.choice("real", "virtual"),
            "real (default) or virtual: simulated time, a run takes no wall time and repeats exactly",
        ),
        "drift": Option(
            opt.number(low=0, low_open=True),
            "wear: factor on c1 and c2 (a twin: its play) at the end of a ramp of drift_samples samples",
        ),
        "drift_samples": Option(opt.integer(minimum=1), "wear: length of the ramp (samples)"),
        "drift_start": Option(opt.integer(), "wear: sample at which the ramp begins (default 0)"),
        "swap_at": Option(
            opt.integer(), "wear: sample of a gear swap that multiplies c1 and c2 (the play) by swap_factor"
        ),
        "swap_factor": Option(opt.number(low=0, low_open=True), "wear: factor on c1 and c2 (the play) from swap_at on"),
    }

    def __init__(
        self,
        *,
        servo: str | Servo = DEFAULT_SERVO,
        twin_options: Mapping[str, Any] | None = None,
        snr: float | None = None,
        noise: float | None = None,
        latency: float = 0.0,
        jitter: float = 0.0,
        drop: float = 0.0,
        timeout: float = 0.05,
        mute_after: int | None = None,
        restart_after: int | None = None,
        seed: int = 0,
        clock: Clock | str | None = None,
        drift: float = 1.0,
        drift_samples: int | None = None,
        drift_start: int = 0,
        swap_at: int | None = None,
        swap_factor: float = 1.0,
        **kwargs: Any,
    ) -> None:
        if isinstance(servo, Servo):
            if twin_options:
                raise ConfigError("give twin_options with a servo name, not with a Servo (it has its parameters)")
            self.servo = servo
        else:
            self.servo = make_servo(servo, **dict(twin_options or {}))
        if snr is not None and noise is not None:
            raise ConfigError(f"give snr (={snr!r}) or noise (={noise!r}), not both")
        kwargs.setdefault("position_unit", UnitConversion(self.servo.unit))
        super().__init__(**kwargs)
        self.noise_std = 0.0 if noise is None else validation.non_negative("noise", noise)
        if snr is not None:
            self.noise_std = reference_output_std(self.servo) / validation.positive("snr", snr)
        if self.servo.twin is not None:
            self._twin_params = self._with_noise(self.servo, self.noise_std, given=snr is not None or noise is not None)
            self.noise_std = self._twin_params.output_encoder_noise_counts * self._resolution()
            # the host reads the twin's output encoder: on the motor, the play lies beyond the readings
            if self._twin_params.output_encoder == "motor":
                self.readings_side = readings_side.MOTOR
        self.latency_ns = int(round(validation.non_negative("latency", latency) * NS_PER_S))
        self.jitter_ns = int(round(validation.non_negative("jitter", jitter) * NS_PER_S))
        self.drop = validation.in_unit_interval("drop", drop, open_low=False, open_high=False)
        self.timeout_ns = int(round(validation.positive("timeout", timeout) * NS_PER_S))
        self.mute_after, self.restart_after = mute_after, restart_after
        self.seed = validation.integer("seed", seed, minimum=0)
        self.wear = Wear(drift=drift, drift_samples=drift_samples, drift_start=drift_start,
                         swap_at=swap_at, swap_factor=swap_factor)  # fmt: skip
        if clock == "virtual":
            clock = VirtualClock()
        elif clock is None or clock == "real":
            clock = MonotonicClock()
        if not isinstance(clock, Clock):
            raise ConfigError(f"clock (={clock!r}) must be 'real', 'virtual' or a Clock")
        self.clock: Clock = clock
        self.device: SimDevice | None = None
        self._boot_id: int | None = None
        self._last_slot: int | None = None
        self._truth_new: TwinTruth | None = None

    @classmethod
    def from_url(cls, url: DriverURL) -> Driver:
        """``sim://SERVO?options``: the host names the servo, options not the driver's own override a twin's."""
        if url.path not in ("", "/"):
            raise ConfigError(f"{url.raw}: a sim:// URL has no path; the servo is its host: sim://xm430?...")
        options = dict(url.options)
        if "plant" in options:
            name = {"bench": "model"}.get(options["plant"], options["plant"])
            raise ConfigError(
                f"{url.raw}: plant= is gone: the servo is the URL's host, sim://{name}?... "
                "(sim://model is the former bench plant)"
            )
        accepted = cls.accepted_options()
        name = url.host or DEFAULT_SERVO
        twin = make_servo(name).is_twin if name.lower() in servo_names() else False
        twin_options = {k: v for k, v in options.items() if k not in accepted and twin}
        unknown = sorted(set(options) - set(accepted) - set(twin_option_names() if twin else ()))
        if unknown:
            valid = ", ".join(sorted(accepted))
            extra = f"; and a twin's parameters: {', '.join(twin_option_names())}" if twin else ""
            raise ConfigError(f"{url.raw}: unknown option(s) {', '.join(unknown)}; sim:// accepts {valid}{extra}")
        driver_options = dataclasses.replace(url, options={k: v for k, v in options.items() if k in accepted})
        driver = cls(servo=name, twin_options=twin_options, **cls.parse_options(driver_options))
        driver.url = url.raw
        return driver

    @property
    def truth(self) -> BacklashModel | None:
        """The pseudo-Wiener model the servo is (when new); None for a twin, of which no such model is true."""
        return self.servo.model

    def truth_at(self, sample: int) -> BacklashModel | None:
        """The pseudo-Wiener model at the servo's sample ``sample``, wear included (None for a twin)."""
        if self.servo.model is None:
            return None
        return self.wear.model(self.servo.model, sample)

    @property
    def twin_truth(self) -> TwinTruth | None:
        """A twin's ground truth when new: play, gear ratio, encoders, loop structure (None for a model plant)."""
        return self.twin_truth_at(0)

    def twin_truth_at(self, sample: int) -> TwinTruth | None:
        """A twin's ground truth at the servo's sample ``sample``: its play as worn by then."""
        if self.servo.twin is None:
            return None
        if self._truth_new is None:
            self._truth_new = Twin(self._twin_params).truth
        return dataclasses.replace(self._truth_new, play_rad=self._truth_new.play_rad * self.wear.factor(sample))

    @property
    def reference_amplitude(self) -> float:
        """Half-width of the uniform input the servo is meant to be excited with (its unit)."""
        return self.servo.amplitude

    # ---- primitives -------------------------------------------------------------------
    def _open(self) -> None:
        rng = np.random.default_rng(self.seed)
        if self.servo.twin is None:
            assert self.servo.model is not None
            plant = SampledPlant(self.servo.model, noise_std=self.noise_std, rng=rng, wear=self.wear)
        else:
            twin = TwinPlant(
                Twin(self._twin_params, seed=self.seed), 1.0 / DEFAULT_RATE_HZ, torque=False, wear=self.wear
            )
            plant = SampledPlant(twin)
        self.device = SimDevice(
            plant, clock=self.clock, latency_ns=self.latency_ns, jitter_ns=self.jitter_ns, drop=self.drop,
            mute_after=self.mute_after, restart_after=self.restart_after, rng=rng,
        )  # fmt: skip
        self._boot_id = self.device.boot_id

    def _close(self) -> None:
        self.device = None

    def _set_torque(self, enabled: bool) -> None:
        plant = self._device().plant
        plant.enable() if enabled else plant.disable()
        self._last_slot = None

    def _set_period(self, period_s: float) -> None:
        self._device().plant.set_period(int(round(period_s * NS_PER_S)))
        self._last_slot = None

    def _exchange(self, command: float, slot: int | None) -> Reading:
        return self._request(command, slot)

    def _read(self) -> Reading:
        return self._request(None, None)

    def _identity(self) -> dict[str, Any]:
        servo = self.servo
        out: dict[str, Any] = {"driver": "sim", "servo": servo.name}
        if servo.model is not None:
            out["model"] = servo.model.to_dict()
        else:
            truth = self.twin_truth
            assert truth is not None
            out["twin"] = dataclasses.asdict(truth)
            if servo.overrides:
                out["overrides"] = {k: str(v) for k, v in servo.overrides.items()}
        out.update(unit=servo.unit, noise_std=self.noise_std, boot_id=self._boot_id)
        if self.wear.active:
            out["wear"] = self.wear.describe()
        return out

    # ---- helpers ----------------------------------------------------------------------
    @staticmethod
    def _with_noise(servo: Servo, noise_std: float, *, given: bool) -> TwinParams:
        """The twin's parameters with ``noise_std`` (rad) as its output encoder's noise (in counts)."""
        params = servo.twin
        assert params is not None
        if not given:
            return params
        if (
            "encoder_noise_counts" in servo.overrides
            or f"{params.output_encoder}_encoder_noise_counts" in servo.overrides
        ):
            raise ConfigError("give the noise as snr=/noise= or as the twin's encoder_noise_counts=, not both")
        counts = noise_std / (2.0 * math.pi / params.output_counts_per_rev)
        return params.replace(**{f"{params.output_encoder}_encoder_noise_counts": counts})

    def _resolution(self) -> float:
        """Output rad per count of the twin's output encoder."""
        return 2.0 * math.pi / self._twin_params.output_counts_per_rev

    def _device(self) -> SimDevice:
        if self.device is None:
            raise DriverError(f"{self.describe()} is not open")
        return self.device

    def _request(self, command: float | None, slot: int | None) -> Reading:
        device = self._device()
        if command is not None and not device.plant.enabled and device.boot_id == self._boot_id:
            raise DriverError(f"{self.describe()}: the torque is off; call enable() first")
        periods = None
        if command is not None and slot is not None:
            if self._last_slot is not None:
                periods = slot - self._last_slot
                if periods < 1:
                    raise DriverError(f"{self.describe()}: slot {slot} does not follow slot {self._last_slot}")
            self._last_slot = slot
        reply = device.request(command, periods)
        if reply is None:
            self.clock.sleep_ns(self.timeout_ns)
            raise DriverTimeout(f"{self.describe()}: no reply within {self.timeout_ns / NS_PER_S:g} s")
        sample, boot_id = reply
        if boot_id != self._boot_id:
            raise DeviceRestarted(
                f"{self.describe()}: the servo restarted (boot id {self._boot_id} -> {boot_id}); "
                "its torque is off and its configuration is lost"
            )
        if sample.fault is not None and command is not None:
            raise DeviceFault(
                f"{self.describe()}: the drive turned its output stage off by itself ({sample.fault} error); "
                "the servo coasts"
            )
        return Reading(position=sample.position, device_time=device.device_time(sample))
