"""The physical servo twin: a small object around the compiled physics and firmware.

Use::

    twin = Twin(preset("xm430"), seed=1)
    twin.enable()                 # torque on: the set point becomes the present position
    twin.command(0.2)             # output rad, latched at the drive's next tick
    twin.advance(0.5)             # run 0.5 s of servo time
    r = twin.read()               # what the drive reports: counts, rad, velocity, current, duty

Time: the twin counts whole sub-steps from :meth:`Twin.reset`; ``advance``
adds the requested time to a running total and runs the sub-steps up to
the nearest sub-step of that total, so many short calls land where one
long call does. The drive's registers change only at its ticks; a reading
is that of the latest tick at or before the current time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.drivers.twin import _layout as L
from servoid.drivers.twin.encoder import counts_to_rad
from servoid.drivers.twin.firmware import control_tick
from servoid.drivers.twin.kernel import RECORD_FIELDS, run, run_sequence
from servoid.drivers.twin.params import TwinParams
from servoid.errors import ConfigError

__all__ = ["Twin", "TwinReading", "TwinTruth", "TwinCounters", "TwinPhysics", "TwinRecord"]

_FAULTS = {L.FAULT_NONE: None, L.FAULT_OVERSPEED: "overspeed"}
_NO_NOISE = np.zeros(0)


@dataclass(frozen=True)
class TwinReading:
    """What the drive reports at its latest tick.

    Attributes
    ----------
    time_s : float
        Time of that tick, s since reset.
    position_rad : float
        The output encoder's reading, output rad (the servo's output).
    load_counts, motor_counts : int or None
        The encoders' counts (None without that encoder).
    load_rad : float or None
        The load encoder's reading, output rad.
    motor_rad : float or None
        The motor encoder's reading, motor-shaft rad.
    velocity_rad_s : float
        The drive's velocity estimate, output rad/s.
    position_estimate_rad : float
        The drive's position estimate on its loop encoder, output rad (an
        ODrive's encoder PLL; the encoder's reading for the others).
    current_a : float
        The winding current the drive measured, A.
    duty : float
        The duty the drive commands, -1..1.
    setpoint_rad : float
        The set point the drive works to (latched, clipped to the travel), output rad.
    enabled : bool
        Whether the output stage is on.
    fault : str or None
        Why the drive turned its output stage off by itself (``"overspeed"``), if it did.
    """

    time_s: float
    position_rad: float
    load_counts: int | None
    motor_counts: int | None
    load_rad: float | None
    motor_rad: float | None
    velocity_rad_s: float
    position_estimate_rad: float
    current_a: float
    duty: float
    setpoint_rad: float
    enabled: bool
    fault: str | None


@dataclass(frozen=True)
class TwinTruth:
    """What is true of the twin, for scoring an identification against it.

    Attributes
    ----------
    name : str
        Preset name.
    play_rad : float
        Total play at the output now, rad.
    gear_ratio : float
        Motor revolutions per output revolution.
    loop_encoder, output_encoder : str
        ``"motor"`` or ``"load"``: the encoder the loop closes on, and the one the output reads.
    structure : str
        The loop structure in words.
    control_rate_hz, current_rate_hz : float
        The firmware's rates.
    substep_s : float
        The integration sub-step.
    output_rad_per_count : float
        Resolution of the output reading, output rad.
    """

    name: str
    play_rad: float
    gear_ratio: float
    loop_encoder: str
    output_encoder: str
    structure: str
    control_rate_hz: float
    current_rate_hz: float
    substep_s: float
    output_rad_per_count: float


@dataclass(frozen=True)
class TwinCounters:
    """Counts a benchmark needs, since reset.

    Attributes
    ----------
    time_s : float
        Servo time run.
    ticks : int
        Control ticks run with the output stage on.
    saturated_ticks : int
        Of those, ticks whose duty (voltage) was at its limit.
    current_limited_ticks : int
        Of those, ticks whose current command was at its limit (cascade drives).
    stuck_motor_s, stuck_load_s : float
        Time the motor / the load spent stuck with the output stage on, s.
    contact_s : float
        Time the gear spent in contact (outside the play), s.
    """

    time_s: float
    ticks: int
    saturated_ticks: int
    current_limited_ticks: int
    stuck_motor_s: float
    stuck_load_s: float
    contact_s: float

    @property
    def saturated_share(self) -> float:
        """Share of the ticks with saturated duty (0 before the first tick)."""
        return self.saturated_ticks / self.ticks if self.ticks else 0.0


@dataclass(frozen=True)
class TwinPhysics:
    """The twin's true continuous state (no encoder in between).

    Attributes
    ----------
    time_s : float
        Now, s since reset.
    motor_rad, motor_rad_s : float
        Motor angle and speed, motor-shaft rad and rad/s.
    gear_side_rad : float
        The motor side of the gear at the output, ``motor_rad / gear_ratio``.
    load_rad, load_rad_s : float
        Load angle and speed, output rad and rad/s.
    current_a, voltage_v : float
        Winding current and terminal voltage.
    contact_torque_nm : float
        Torque the gear passes to the load (0 inside the play).
    motor_stuck, load_stuck : bool
        The stick states.
    """

    time_s: float
    motor_rad: float
    motor_rad_s: float
    gear_side_rad: float
    load_rad: float
    load_rad_s: float
    current_a: float
    voltage_v: float
    contact_torque_nm: float
    motor_stuck: bool
    load_stuck: bool


@dataclass(frozen=True)
class TwinRecord:
    """A host-sampled run (:meth:`Twin.sample`); arrays are one entry per host instant.

    Attributes
    ----------
    t_s : numpy.ndarray
        The host instants, s since reset.
    u : numpy.ndarray
        The set point sent at each instant, output rad.
    y : numpy.ndarray
        The output encoder's reading at each instant (before its command), output rad.
    load_rad, motor_rad : numpy.ndarray or None
        The encoders' readings (output rad; motor-shaft rad), None without that encoder.
    velocity_rad_s, current_a, duty : numpy.ndarray
        The drive's other registers.
    true_load_rad, true_gear_side_rad : numpy.ndarray
        Ground truth at each instant: the load angle and the motor side of
        the gear (``theta_m / N``), output rad.
    reading_age_s : numpy.ndarray
        How old each reading was: the instant minus the drive's latest tick, s.
    """

    t_s: np.ndarray
    u: np.ndarray
    y: np.ndarray
    load_rad: np.ndarray | None
    motor_rad: np.ndarray | None
    velocity_rad_s: np.ndarray
    current_a: np.ndarray
    duty: np.ndarray
    true_load_rad: np.ndarray
    true_gear_side_rad: np.ndarray
    reading_age_s: np.ndarray


class Twin:
    """A physically modelled servo: motor, friction, gear with play, load, encoders, the drive's loops.

    Parameters
    ----------
    params : TwinParams
        The servo (a preset, possibly with overrides: :func:`servoid.drivers.twin.preset`).
    seed : int
        Seed of the encoder noise (one stream per encoder); the same seed gives
        the same run, bit for bit.

    Notes
    -----
    Timing convention of the host: a reading is the drive's registers at its
    latest tick; a command waits for the drive's next tick and is then held
    until the next command (sample-and-hold at the host's rate).
    """

    def __init__(self, params: TwinParams, *, seed: int = 0) -> None:
        if not isinstance(params, TwinParams):
            raise ConfigError(
                f"params must be TwinParams (from servoid.drivers.twin.preset), got {type(params).__name__}"
            )
        self._params = params
        self._seed = validation.integer("seed", seed, minimum=0)
        self._phys, self._fw = params.pack()
        self._h = params.substep_s
        self._spt = int(self._fw[L.F_SPT])
        self.reset()

    # -- set-up -----------------------------------------------------------------
    @property
    def params(self) -> TwinParams:
        """The parameters (the play as built; :attr:`truth` has the play now)."""
        return self._params

    @property
    def time_s(self) -> float:
        """Servo time since reset, s."""
        return float(self._state[L.S_K] * self._h)

    def reset(self) -> None:
        """Back to rest at zero, torque off, counters and noise streams restarted (a power cycle)."""
        self._state = np.zeros(L.S_SIZE)
        self._mem = np.zeros(L.M_SIZE)
        self._state[L.S_STUCK_M] = 1.0
        self._state[L.S_STUCK_L] = 1.0
        self._mem[L.M_FIRST] = 1.0
        self._requested_s = 0.0
        streams = np.random.SeedSequence(self._seed).spawn(2)
        self._rng_m = np.random.default_rng(streams[0])
        self._rng_l = np.random.default_rng(streams[1])
        self._noisy_m = self._phys[L.P_NOISE_M] > 0.0 and self._phys[L.P_CPR_M] > 0.0
        self._noisy_l = self._phys[L.P_NOISE_L] > 0.0 and self._phys[L.P_CPR_L] > 0.0
        # the drive samples its encoders at power-up (tick 0)
        nm, nl = self._draw(1)
        control_tick(self._phys, self._fw, self._state, self._mem, nm[0] if nm.size else 0.0, nl[0] if nl.size else 0.0)

    def enable(self) -> None:
        """Torque on. The set point becomes the present position (zero torque), so nothing jumps (as the vendors do)."""
        if self._state[L.S_ENABLED] > 0.5:
            return
        self._state[L.S_ENABLED] = 1.0
        self._state[L.S_FAULT] = L.FAULT_NONE
        self._mem[:] = 0.0
        self._mem[L.M_FIRST] = 1.0
        self._hold()

    @property
    def mode(self) -> str:
        """``"position"`` (set points in output rad) or ``"torque"`` (motor torque, N m)."""
        return "torque" if self._state[L.S_MODE] == L.MODE_TORQUE else "position"

    def set_mode(self, mode: str) -> None:
        """What :meth:`command` means from now on: a position or, for a cascade drive, a motor torque.

        Parameters
        ----------
        mode : {"position", "torque"}
            ``torque``: the drive runs its current loop alone on ``torque /
            Kt`` (CiA 402 cyclic synchronous torque, ODrive torque control);
            the set point starts at zero torque, a position set point at the
            present position.

        Raises
        ------
        ConfigError
            An unknown mode, or torque on a drive without a current loop.
        """
        if mode not in ("position", "torque"):
            raise ConfigError(f"mode (={mode!r}) must be 'position' or 'torque'")
        if mode == "torque" and self._params.firmware != "cascade":
            raise ConfigError(
                f"the {self._params.name} twin has no current loop (firmware {self._params.firmware}): "
                "it runs in position mode only"
            )
        if mode == self.mode:
            return
        self._state[L.S_MODE] = L.MODE_TORQUE if mode == "torque" else L.MODE_POSITION
        self._hold()

    def _hold(self) -> None:
        """Set the set point to what keeps the servo as it is: the present position, or no torque."""
        self._state[L.S_SP] = 0.0 if self._state[L.S_MODE] == L.MODE_TORQUE else self._loop_position()
        self._state[L.S_HAS_PENDING] = 0.0

    def disable(self) -> None:
        """Torque off: the output stage opens, the motor and load coast."""
        self._state[L.S_ENABLED] = 0.0
        self._state[L.S_V] = 0.0
        self._state[L.S_I_CMD] = 0.0
        self._state[L.S_DUTY] = 0.0

    def set_play(self, play_rad: float) -> None:
        """Change the play while running (wear), total at the output, rad.

        Parameters
        ----------
        play_rad : float
            The new play, >= 0 and below the travel.
        """
        play = validation.non_negative("play_rad", play_rad)
        if play >= self._params.range_rad:
            raise ConfigError(
                f"play_rad (={play!r}) must be smaller than the range range_rad (={self._params.range_rad!r})"
            )
        self._phys[L.P_HALF_PLAY] = 0.5 * play

    # -- running ----------------------------------------------------------------
    def command(self, u: float) -> None:
        """Send a set point; the drive latches it at its next tick.

        Parameters
        ----------
        u : float
            Position set point at the output, rad (torque mode: motor torque, N m).
        """
        self._state[L.S_PENDING] = validation.real("u", u)
        self._state[L.S_HAS_PENDING] = 1.0

    def advance(self, dt_s: float) -> None:
        """Run ``dt_s`` seconds of servo time.

        Parameters
        ----------
        dt_s : float
            Time to run, s (>= 0).
        """
        dt = validation.non_negative("dt_s", dt_s)
        self._requested_s += dt
        k0 = int(self._state[L.S_K])
        n = int(round(self._requested_s / self._h)) - k0
        if n <= 0:
            return
        nm, nl = self._draw((k0 + n) // self._spt - k0 // self._spt)
        run(self._phys, self._fw, self._state, self._mem, n, nm, nl, 0)

    def read(self) -> TwinReading:
        """The drive's registers at its latest tick."""
        s = self._state
        p = self._params
        load_counts = int(s[L.S_CNT_L]) if p.load_encoder_cpr else None
        motor_counts = int(s[L.S_CNT_M]) if p.motor_encoder_cpr else None
        load_rad = float(counts_to_rad(s[L.S_CNT_L], p.load_encoder_cpr)) if load_counts is not None else None
        motor_rad = float(counts_to_rad(s[L.S_CNT_M], p.motor_encoder_cpr)) if motor_counts is not None else None
        position = load_rad if p.output_encoder == "load" else motor_rad / p.gear_ratio  # type: ignore[operator]
        return TwinReading(
            time_s=float(s[L.S_TICK_K] * self._h),
            position_rad=float(position),  # type: ignore[arg-type]
            load_counts=load_counts,
            motor_counts=motor_counts,
            load_rad=load_rad,
            motor_rad=motor_rad,
            velocity_rad_s=float(s[L.S_VEL]),
            position_estimate_rad=float(s[L.S_POS_EST]),
            current_a=float(s[L.S_CUR]),
            duty=float(s[L.S_DUTY]),
            setpoint_rad=float(s[L.S_SP]),
            enabled=bool(s[L.S_ENABLED] > 0.5),
            fault=_FAULTS.get(int(s[L.S_FAULT]), "unknown"),
        )

    def sample(self, u: np.ndarray, period_s: float) -> TwinRecord:
        """Play set points at a host's rate and record what the host reads.

        At each host instant ``t_j = t_0 + j * period_s`` (rounded to the
        sub-step) the host reads the drive's registers (the reading belongs
        to the drive's latest tick at or before ``t_j``), then sends ``u[j]``,
        which the drive latches at its next tick. So ``y[j]`` depends on
        ``u[j-1]`` and earlier. The twin keeps running from where it is
        (enable it first); one call gives exactly what the same reads,
        commands and :meth:`advance` calls one by one give.

        Parameters
        ----------
        u : array_like
            Set points, output rad.
        period_s : float
            The host's sample period, s.

        Returns
        -------
        TwinRecord
        """
        u_arr = validation.signal("u", u)
        period = validation.positive("period_s", period_s)
        start = self._requested_s
        k0 = int(self._state[L.S_K])
        ends = np.rint((start + period * np.arange(1, u_arr.size + 1)) / self._h).astype(np.int64)
        n_sub = np.diff(np.concatenate(([k0], ends)))
        n_sub[n_sub < 0] = 0
        nm, nl = self._draw(int(ends[-1]) // self._spt - k0 // self._spt)
        out = np.empty((u_arr.size, len(RECORD_FIELDS)))
        t = (np.concatenate(([k0], ends[:-1]))) * self._h
        run_sequence(self._phys, self._fw, self._state, self._mem, u_arr, n_sub, nm, nl, out)
        self._requested_s = start + period * u_arr.size
        return self._record(t, u_arr, out)

    # -- what is true -----------------------------------------------------------
    @property
    def truth(self) -> TwinTruth:
        """Ground truth: play now, ratio, which encoder does what, the loop structure."""
        p = self._params
        return TwinTruth(
            name=p.name,
            play_rad=2.0 * float(self._phys[L.P_HALF_PLAY]),
            gear_ratio=p.gear_ratio,
            loop_encoder=p.loop_encoder,
            output_encoder=p.output_encoder,
            structure=p.structure,
            control_rate_hz=p.control_rate_hz,
            current_rate_hz=p.current_rate_hz,
            substep_s=self._h,
            output_rad_per_count=2.0 * math.pi / p.output_counts_per_rev,
        )

    @property
    def counters(self) -> TwinCounters:
        """Tick, saturation, stick and contact counts since reset."""
        s = self._state
        return TwinCounters(
            time_s=self.time_s,
            ticks=int(s[L.S_N_TICKS]),
            saturated_ticks=int(s[L.S_N_SAT]),
            current_limited_ticks=int(s[L.S_N_CUR_LIM]),
            stuck_motor_s=float(s[L.S_N_STUCK_M] * self._h),
            stuck_load_s=float(s[L.S_N_STUCK_L] * self._h),
            contact_s=float(s[L.S_N_CONTACT] * self._h),
        )

    def physics(self) -> TwinPhysics:
        """The true continuous state now."""
        s = self._state
        return TwinPhysics(
            time_s=self.time_s,
            motor_rad=float(s[L.S_TH_M]),
            motor_rad_s=float(s[L.S_W_M]),
            gear_side_rad=float(s[L.S_TH_M] / self._params.gear_ratio),
            load_rad=float(s[L.S_TH_L]),
            load_rad_s=float(s[L.S_W_L]),
            current_a=float(s[L.S_I]),
            voltage_v=float(s[L.S_V]),
            contact_torque_nm=float(s[L.S_TORQUE_C]),
            motor_stuck=bool(s[L.S_STUCK_M] > 0.5),
            load_stuck=bool(s[L.S_STUCK_L] > 0.5),
        )

    def place(
        self,
        *,
        load_rad: float = 0.0,
        gear_side_rad: float | None = None,
        load_rad_s: float = 0.0,
        motor_rad_s: float = 0.0,
    ) -> None:
        """Put the bodies somewhere (torque off first): for experiments that start in the play.

        Parameters
        ----------
        load_rad : float
            Load angle, output rad.
        gear_side_rad : float, optional
            Motor side of the gear, output rad (default: the load's angle, mid-play).
        load_rad_s : float
            Load speed, output rad/s.
        motor_rad_s : float
            Motor speed, motor rad/s.
        """
        n = self._params.gear_ratio
        s = self._state
        s[L.S_TH_L] = validation.real("load_rad", load_rad)
        s[L.S_TH_M] = n * validation.real("gear_side_rad", load_rad if gear_side_rad is None else gear_side_rad)
        s[L.S_W_L] = validation.real("load_rad_s", load_rad_s)
        s[L.S_W_M] = validation.real("motor_rad_s", motor_rad_s)
        s[L.S_STUCK_L] = 1.0 if s[L.S_W_L] == 0.0 else 0.0
        s[L.S_STUCK_M] = 1.0 if s[L.S_W_M] == 0.0 else 0.0

    # -- helpers ----------------------------------------------------------------
    def _draw(self, ticks: int) -> tuple[np.ndarray, np.ndarray]:
        """Standard normal draws for the next ``ticks`` encoder samples (empty without noise)."""
        nm = self._rng_m.standard_normal(ticks) if self._noisy_m and ticks > 0 else _NO_NOISE
        nl = self._rng_l.standard_normal(ticks) if self._noisy_l and ticks > 0 else _NO_NOISE
        return nm, nl

    def _loop_position(self) -> float:
        """The loop encoder's reading as an output angle."""
        p = self._params
        if p.loop_encoder == "load":
            return counts_to_rad(float(self._state[L.S_CNT_L]), p.load_encoder_cpr)
        return counts_to_rad(float(self._state[L.S_CNT_M]), p.motor_encoder_cpr) / p.gear_ratio

    def _record(self, t: np.ndarray, u: np.ndarray, out: np.ndarray) -> TwinRecord:
        p = self._params
        col = {name: out[:, i] for i, name in enumerate(RECORD_FIELDS)}
        load = counts_to_rad(col["load_counts"], p.load_encoder_cpr) if p.load_encoder_cpr else None
        motor = counts_to_rad(col["motor_counts"], p.motor_encoder_cpr) if p.motor_encoder_cpr else None
        y = load if p.output_encoder == "load" else motor / p.gear_ratio  # type: ignore[operator]
        return TwinRecord(
            t_s=t,
            u=u.copy(),
            y=np.asarray(y),
            load_rad=load,
            motor_rad=motor,
            velocity_rad_s=col["velocity"].copy(),
            current_a=col["current"].copy(),
            duty=col["duty"].copy(),
            true_load_rad=col["theta_l"].copy(),
            true_gear_side_rad=col["theta_m"] / p.gear_ratio,
            reading_age_s=t - col["tick_k"] * self._h,
        )
