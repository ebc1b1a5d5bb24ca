"""The simulated servo: the backlash plant behind the driver interface, ``sim://``.

URL::

    sim://?plant=bench&snr=40&latency=0.0002&drop=0.01&seed=1
    sim://?plant=gear&snr=40&clock=virtual&drift=1.5&drift_samples=200000   (a wearing gear)

It is a driver like any other (same registry, same contract tests, same
failure behaviour) with its time taken from an injected
:class:`~servoid.drivers.clock.Clock`: give it and the sampling session one
:class:`~servoid.drivers.clock.VirtualClock` and every run, including its
late, missed and timed-out samples, is reproducible on any machine.

The device side (:class:`SimDevice`) is kept apart from the driver side, as
on a real link: the device has a boot id and a clock that restart when it
restarts, drops replies, goes silent; the driver only sees replies (or their
absence) and detects the restart from the boot id.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from servoid import validation
from servoid.drivers import options as opt
from servoid.drivers.base import Driver, Option, Reading, UnitConversion
from servoid.drivers.clock import NS_PER_S, Clock, MonotonicClock, VirtualClock
from servoid.drivers.model_plant import MODEL_AMPLITUDE, MODEL_PLANT, MODEL_UNIT
from servoid.drivers.sampled import PlantSample, SampledPlant
from servoid.errors import ConfigError, DeviceRestarted, DriverError, DriverTimeout
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import simulate
from servoid.ident.models.wear import GEAR_PLANT, Wear
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE, PAPER_PLANT

__all__ = ["SimDriver", "SimDevice", "SimPlant", "SIM_PLANTS"]


@dataclass(frozen=True)
class SimPlant:
    """A plant the simulated servo can be.

    Attributes
    ----------
    model : BacklashModel
        Its parameters.
    unit : str
        Unit of command and position.
    amplitude : float
        Half-width of the uniform input it is meant to be excited with (it
        visits both backlash lines); also the reference of ``snr``.
    """

    model: BacklashModel
    unit: str
    amplitude: float


#: ``plant=`` choices of the URL.
SIM_PLANTS: dict[str, SimPlant] = {
    "bench": SimPlant(MODEL_PLANT, MODEL_UNIT, MODEL_AMPLITUDE),
    "paper": SimPlant(PAPER_PLANT, "unit", PAPER_INPUT_AMPLITUDE),
    "gear": SimPlant(GEAR_PLANT, "unit", PAPER_INPUT_AMPLITUDE),
}


def reference_output_std(plant: SimPlant) -> float:
    """Standard deviation of the plant's output under its reference input (the base of ``snr``)."""
    u = np.random.default_rng(0).uniform(-plant.amplitude, plant.amplitude, 20_000)
    return float(np.std(simulate(plant.model, u).y_clean))


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
    """The simulated bench servo (``sim://``).

    Parameters
    ----------
    plant : {"bench", "paper", "gear"}
        ``bench``: :data:`~servoid.drivers.model_plant.MODEL_PLANT` in rad;
        ``paper``: the paper's Section 4 plant, unitless; ``gear``: the paper's
        plant with a new gear, ``c1 + c2 = 1`` (:data:`~servoid.ident.models.wear.GEAR_PLANT`).
    snr : float, optional
        Measurement noise as a signal-to-noise ratio: noise standard deviation
        = std of the output under the plant's reference input / ``snr``.
    noise : float, optional
        Measurement noise standard deviation, plant unit (instead of ``snr``).
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
        ``c1`` and ``c2`` ramp by the factor ``drift`` over ``drift_samples``
        samples from sample ``drift_start``, and are multiplied by
        ``swap_factor`` from sample ``swap_at`` on (a gear swap). Samples are
        the plant's own, so the wear follows time, not the host's requests.
    **kwargs
        Limits and units for :class:`~servoid.drivers.base.Driver`.
    """

    scheme: ClassVar[str] = "sim"
    carries_slots: ClassVar[bool] = True  # the simulated plant steps on the session's slots
    options: ClassVar[Mapping[str, Option]] = {
        "plant": Option(opt.choice(*SIM_PLANTS), f"simulated plant: {' or '.join(SIM_PLANTS)} (default bench)"),
        "snr": Option(
            opt.number(low=0, low_open=True), "measurement noise as sqrt(var(y)/var(noise)) under the reference input"
        ),
        "noise": Option(opt.number(low=0), "measurement noise standard deviation (plant unit)"),
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
            opt.number(low=0, low_open=True), "wear: factor on c1 and c2 at the end of a ramp of drift_samples samples"
        ),
        "drift_samples": Option(opt.integer(minimum=1), "wear: length of the ramp (samples)"),
        "drift_start": Option(opt.integer(), "wear: sample at which the ramp begins (default 0)"),
        "swap_at": Option(opt.integer(), "wear: sample of a gear swap that multiplies c1 and c2 by swap_factor"),
        "swap_factor": Option(opt.number(low=0, low_open=True), "wear: factor on c1 and c2 from swap_at on"),
    }

    def __init__(
        self,
        *,
        plant: str = "bench",
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
        if plant not in SIM_PLANTS:
            raise ConfigError(f"plant (={plant!r}) must be one of {', '.join(SIM_PLANTS)}")
        if snr is not None and noise is not None:
            raise ConfigError(f"give snr (={snr!r}) or noise (={noise!r}), not both")
        self.sim_plant = SIM_PLANTS[plant]
        kwargs.setdefault("position_unit", UnitConversion(self.sim_plant.unit))
        super().__init__(**kwargs)
        self.plant_name = plant
        self.noise_std = 0.0 if noise is None else validation.non_negative("noise", noise)
        if snr is not None:
            self.noise_std = reference_output_std(self.sim_plant) / validation.positive("snr", snr)
        self.latency_ns = int(round(validation.non_negative("latency", latency) * NS_PER_S))
        self.jitter_ns = int(round(validation.non_negative("jitter", jitter) * NS_PER_S))
        self.drop = validation.in_unit_interval("drop", drop, open_low=False, open_high=False)
        self.timeout_ns = int(round(validation.positive("timeout", timeout) * NS_PER_S))
        self.mute_after, self.restart_after = mute_after, restart_after
        self.seed = seed
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

    @property
    def truth(self) -> BacklashModel:
        """The simulated plant's true parameters (when new: see :meth:`truth_at` for a wearing one)."""
        return self.sim_plant.model

    def truth_at(self, sample: int) -> BacklashModel:
        """The true parameters at the plant's sample ``sample``, wear included."""
        return self.wear.model(self.sim_plant.model, sample)

    @property
    def reference_amplitude(self) -> float:
        """Half-width of the uniform input the plant is meant to be excited with (plant unit)."""
        return self.sim_plant.amplitude

    # ---- primitives -------------------------------------------------------------------
    def _open(self) -> None:
        rng = np.random.default_rng(self.seed)
        plant = SampledPlant(self.sim_plant.model, noise_std=self.noise_std, rng=rng, wear=self.wear)
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
        return {
            "driver": "sim",
            "plant": self.plant_name,
            "model": self.sim_plant.model.to_dict(),
            "unit": self.sim_plant.unit,
            "noise_std": self.noise_std,
            "boot_id": self._boot_id,
            **({"wear": self.wear.describe()} if self.wear.active else {}),
        }

    # ---- helpers ----------------------------------------------------------------------
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
        return Reading(position=sample.position, device_time=device.device_time(sample))
