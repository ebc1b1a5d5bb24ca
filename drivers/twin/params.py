"""A twin's parameters: one frozen, validated record in SI units, and its overrides by name.

Every parameter has a name that says its unit (``load_inertia_kgm2``,
``play_rad``); a few aliases take the units people measure in
(``play_deg``, ``play_arcmin``, ``encoder_noise_counts``). Overrides arrive
from code or from a URL (``sim://xm430?play_deg=0.8``), so text values are
parsed; an unknown name or a bad value is a one-line
:class:`~servoid.errors.ConfigError` naming it.

Conventions (stated once, used by every module of the twin):

* the **play** ``play_rad`` is the total free angle at the output: with the
  motor held, the load moves ``play_rad`` from one flank to the other;
* angles of the **motor** are motor-shaft radians; the gear side of the
  motor is ``theta_motor / gear_ratio``; the gear's stiffness, damping and
  play and everything about the load are on the **output** side;
* the motor's **current** and **voltage** are those of a DC motor; for a
  three-phase motor they are the power-invariant DC equivalent of the
  q axis (current = q-axis current, so ``torque = Kt * current``;
  ``back_emf_v_s == torque_constant_nm_a``; resistance and inductance 1.5
  times the phase values);
* **gravity** pulls the load with ``-m g l sin(theta_load)``: the link hangs
  down at ``theta_load = 0``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.drivers.twin import _layout as L
from servoid.errors import ConfigError

__all__ = ["TwinParams", "FIRMWARES", "ENCODER_SIDES", "ALIASES", "override"]

#: Firmware structures a twin can run (see :mod:`servoid.drivers.twin.firmware`).
FIRMWARES = ("dynamixel_position", "feetech_position", "cascade")
#: Where an encoder can sit.
ENCODER_SIDES = ("motor", "load")
#: Override names in other units: alias -> (parameter, factor).
ALIASES: dict[str, tuple[str, float]] = {
    "play_deg": ("play_rad", math.pi / 180.0),
    "play_arcmin": ("play_rad", math.pi / 10800.0),
    "range_deg": ("range_rad", math.pi / 180.0),
}
_G = 9.80665  # standard gravity, m/s^2


@dataclass(frozen=True, kw_only=True)
class TwinParams:
    """Everything a physical servo twin is built from (SI units unless the name says otherwise).

    Parameters
    ----------
    name : str
        Preset name (``"xm430"``) or a label of your own.
    description : str
        One line: what hardware this is.
    supply_v : float
        Supply voltage: the terminal voltage at duty 1, V.
    max_duty : float
        Largest duty the output stage makes, in (0, 1] (0.9 for a drive that
        keeps 10 % headroom; the modulation limit for a three-phase drive).
    motor_inertia_kgm2 : float
        Rotor inertia, with the gear's input stage, kg m^2.
    motor_viscous_nms : float
        Motor-side viscous friction, N m s/rad.
    motor_coulomb_nm : float
        Motor-side Coulomb (sliding) friction, N m.
    motor_breakaway_nm : float
        Motor-side break-away (static) friction, N m, >= the Coulomb level: a
        stuck motor stays stuck until the torque on it exceeds this.
    motor_stribeck_rad_s : float
        Speed over which sliding friction falls from break-away to Coulomb, motor rad/s.
    torque_constant_nm_a : float
        N m per A.
    back_emf_v_s : float
        V per rad/s (equal to the torque constant in SI for a lossless motor model).
    resistance_ohm : float
        Winding resistance plus the output stage's, ohm.
    inductance_h : float
        Winding inductance, H (0: the current follows the voltage at once).
    gear_ratio : float
        Motor revolutions per output revolution (> 0).
    play_rad : float
        Total play at the output, rad (>= 0, below ``range_rad``).
    gear_stiffness_nm_rad : float
        Torsional stiffness of the gear train in contact, N m/rad at the output.
    gear_damping_nms : float
        Damping of the gear train in contact, N m s/rad at the output.
    gear_efficiency : float
        Efficiency of the gear train, in (0, 1]: the load gets ``efficiency``
        of the torque the motor pushes through it; a load driving the motor
        back loses the same share.
    load_inertia_kgm2 : float
        Load inertia (horn, link, payload), kg m^2.
    load_viscous_nms : float
        Load viscous friction, N m s/rad.
    load_coulomb_nm : float
        Load Coulomb friction, N m.
    load_breakaway_nm : float
        Load break-away friction, N m (>= ``load_coulomb_nm``).
    load_stribeck_rad_s : float
        Stribeck speed of the load's friction, rad/s.
    load_mass_kg : float
        Mass of a pendulum link (0: no gravity), kg.
    load_arm_m : float
        Distance from the axis to the link's centre of mass, m.
    motor_encoder_cpr : int
        Motor encoder counts per motor revolution (0: no motor encoder).
    load_encoder_cpr : int
        Load encoder counts per output revolution (0: no load encoder).
    motor_encoder_noise_counts : float
        Standard deviation of the motor encoder's noise, counts.
    load_encoder_noise_counts : float
        Standard deviation of the load encoder's noise, counts.
    loop_encoder : {"motor", "load"}
        The encoder the drive's position loop closes on.
    output_encoder : {"motor", "load"}
        The encoder whose reading is the servo's output (what the host records).
    firmware : {"dynamixel_position", "feetech_position", "cascade"}
        The drive's loop structure.
    control_rate_hz : float
        Rate of the position (and velocity) loop, Hz.
    current_rate_hz : float
        Rate of the current loop, Hz (the control rate for firmware without one).
    substeps : int
        Integration sub-steps per current-loop tick.
    range_rad : float
        Travel the firmware accepts, rad: set points are clipped to
        ``[-range_rad/2, range_rad/2]`` (inf: no limit).
    velocity_filter_s : float
        Time constant of the drive's velocity estimate (a first-order filter
        of the encoder's differences), s.
    pll_bandwidth_rad_s : float
        > 0: the drive estimates position and velocity with an encoder PLL
        of this bandwidth instead (as an ODrive does), rad/s.
    pos_p : float
        PID firmware: position P gain as written in the control table.
    pos_i : float
        PID firmware: position I gain as written in the control table.
    pos_d : float
        PID firmware: position D gain as written in the control table.
    p_scale : float
        PID firmware: vendor output units per count of error per unit of ``pos_p``.
    i_scale : float
        PID firmware: output units per count-tick of summed error per unit of ``pos_i``.
    d_scale : float
        PID firmware: output units per count-per-tick of error change per unit of ``pos_d``.
    output_limit : float
        PID firmware: output limit in vendor units (Dynamixel PWM Limit,
        Feetech torque limit).
    output_full_scale : float
        PID firmware: vendor units that mean 100 % duty.
    deadband_counts : float
        PID firmware: error band, counts, inside which the output is off.
    min_output : float
        PID firmware: smallest output outside the dead band, vendor units.
    pos_kv_1_s : float
        Cascade: position gain, (rad/s) per rad of the loop encoder's shaft.
    vel_kp_a_rad_s : float
        Cascade: velocity P gain, A per rad/s.
    vel_ki_a_rad : float
        Cascade: velocity I gain, A per rad.
    vel_limit_rad_s : float
        Cascade: velocity command limit on the loop encoder's shaft, rad/s (inf: none).
    overspeed_ratio : float
        Cascade: the drive faults (output stage off) when the velocity
        estimate exceeds this times ``vel_limit_rad_s`` (inf: never).
    integrator_decay : float
        Cascade: factor applied per tick to an integrator whose loop is
        saturated (ODrive: 0.99); 1 holds it (conditional integration).
    cur_kp_v_a : float
        Cascade: current P gain, V/A.
    cur_ki_v_as : float
        Cascade: current I gain, V/(A s).
    current_limit_a : float
        Cascade: current command limit, A.
    """

    name: str
    description: str
    supply_v: float
    max_duty: float
    motor_inertia_kgm2: float
    motor_viscous_nms: float
    motor_coulomb_nm: float
    motor_breakaway_nm: float
    motor_stribeck_rad_s: float
    torque_constant_nm_a: float
    back_emf_v_s: float
    resistance_ohm: float
    inductance_h: float
    gear_ratio: float
    play_rad: float
    gear_stiffness_nm_rad: float
    gear_damping_nms: float
    gear_efficiency: float
    load_inertia_kgm2: float
    load_viscous_nms: float
    load_coulomb_nm: float
    load_breakaway_nm: float
    load_stribeck_rad_s: float
    load_mass_kg: float = 0.0
    load_arm_m: float = 0.0
    motor_encoder_cpr: int
    load_encoder_cpr: int
    motor_encoder_noise_counts: float = 0.0
    load_encoder_noise_counts: float = 0.0
    loop_encoder: str
    output_encoder: str
    firmware: str
    control_rate_hz: float
    current_rate_hz: float
    substeps: int
    range_rad: float
    velocity_filter_s: float = 0.0
    pll_bandwidth_rad_s: float = 0.0
    pos_p: float = 0.0
    pos_i: float = 0.0
    pos_d: float = 0.0
    p_scale: float = 1.0
    i_scale: float = 1.0
    d_scale: float = 1.0
    output_limit: float = 1.0
    output_full_scale: float = 1.0
    deadband_counts: float = 0.0
    min_output: float = 0.0
    pos_kv_1_s: float = 0.0
    vel_kp_a_rad_s: float = 0.0
    vel_ki_a_rad: float = 0.0
    vel_limit_rad_s: float = math.inf
    overspeed_ratio: float = math.inf
    integrator_decay: float = 1.0
    cur_kp_v_a: float = 0.0
    cur_ki_v_as: float = 0.0
    current_limit_a: float = math.inf

    def __post_init__(self) -> None:
        _validate(self)

    # -- derived quantities ----------------------------------------------------
    @property
    def substep_s(self) -> float:
        """Integration sub-step, s."""
        return 1.0 / (self.current_rate_hz * self.substeps)

    @property
    def output_counts_per_rev(self) -> float:
        """Counts of the output encoder per output revolution (a motor encoder's times the ratio)."""
        if self.output_encoder == "load":
            return float(self.load_encoder_cpr)
        return self.motor_encoder_cpr * self.gear_ratio

    @property
    def output_encoder_noise_counts(self) -> float:
        """Noise of the output encoder, counts (standard deviation)."""
        return self.load_encoder_noise_counts if self.output_encoder == "load" else self.motor_encoder_noise_counts

    @property
    def structure(self) -> str:
        """The loop structure in words."""
        where = f"closed on the {self.loop_encoder} encoder"
        if self.firmware == "cascade":
            return (
                f"position P ({self.control_rate_hz:g} Hz) -> velocity PI ({self.control_rate_hz:g} Hz) -> "
                f"current PI ({self.current_rate_hz:g} Hz) -> voltage, {where}"
            )
        vendor = "Dynamixel" if self.firmware == "dynamixel_position" else "Feetech"
        return f"{vendor} position PID ({self.control_rate_hz:g} Hz) -> PWM duty, no current loop, {where}"

    def replace(self, **changes: Any) -> TwinParams:
        """A copy with ``changes`` applied (validated)."""
        return dataclasses.replace(self, **changes)

    def pack(self) -> tuple[np.ndarray, np.ndarray]:
        """The ``phys`` and ``fw`` arrays of :mod:`servoid.drivers.twin._layout`."""
        h = self.substep_s
        phys = np.zeros(L.P_SIZE)
        phys[L.P_H] = h
        phys[L.P_J_M] = self.motor_inertia_kgm2
        phys[L.P_B_M] = self.motor_viscous_nms
        phys[L.P_TC_M] = self.motor_coulomb_nm
        phys[L.P_TS_M] = self.motor_breakaway_nm
        phys[L.P_VS_M] = self.motor_stribeck_rad_s
        phys[L.P_KT] = self.torque_constant_nm_a
        phys[L.P_KE] = self.back_emf_v_s
        phys[L.P_R] = self.resistance_ohm
        phys[L.P_L] = self.inductance_h
        # the current's exact step for a voltage and speed held over the sub-step
        phys[L.P_EL_DECAY] = math.exp(-h * self.resistance_ohm / self.inductance_h) if self.inductance_h > 0 else 0.0
        phys[L.P_VSUP] = self.supply_v
        phys[L.P_DUTY_MAX] = self.max_duty
        phys[L.P_N] = self.gear_ratio
        phys[L.P_HALF_PLAY] = 0.5 * self.play_rad
        phys[L.P_K] = self.gear_stiffness_nm_rad
        phys[L.P_C] = self.gear_damping_nms
        phys[L.P_ETA] = self.gear_efficiency
        phys[L.P_J_L] = self.load_inertia_kgm2
        phys[L.P_B_L] = self.load_viscous_nms
        phys[L.P_TC_L] = self.load_coulomb_nm
        phys[L.P_TS_L] = self.load_breakaway_nm
        phys[L.P_VS_L] = self.load_stribeck_rad_s
        phys[L.P_MGL] = self.load_mass_kg * _G * self.load_arm_m
        phys[L.P_CPR_M] = self.motor_encoder_cpr
        phys[L.P_CPR_L] = self.load_encoder_cpr
        phys[L.P_NOISE_M] = self.motor_encoder_noise_counts
        phys[L.P_NOISE_L] = self.load_encoder_noise_counts

        fw = np.zeros(L.F_SIZE)
        fw[L.F_KIND] = FIRMWARES.index(self.firmware)
        spc = self.substeps
        fw[L.F_SPC] = spc
        fw[L.F_SPT] = spc * round(self.current_rate_hz / self.control_rate_hz)
        fw[L.F_LOOP_ENC] = ENCODER_SIDES.index(self.loop_encoder)
        fw[L.F_DT] = 1.0 / self.control_rate_hz
        fw[L.F_DT_C] = 1.0 / self.current_rate_hz
        fw[L.F_SP_MIN] = -0.5 * self.range_rad
        fw[L.F_SP_MAX] = 0.5 * self.range_rad
        fw[L.F_VEL_TAU] = self.velocity_filter_s
        fw[L.F_PLL_BW] = self.pll_bandwidth_rad_s
        fw[L.F_KP] = self.pos_p * self.p_scale
        fw[L.F_KI] = self.pos_i * self.i_scale
        fw[L.F_KD] = self.pos_d * self.d_scale
        fw[L.F_OUT_LIMIT] = self.output_limit
        fw[L.F_OUT_FULL] = self.output_full_scale
        fw[L.F_DEADBAND] = self.deadband_counts
        fw[L.F_MIN_OUT] = self.min_output
        fw[L.F_POS_KV] = self.pos_kv_1_s
        fw[L.F_VEL_KP] = self.vel_kp_a_rad_s
        fw[L.F_VEL_KI] = self.vel_ki_a_rad
        fw[L.F_VEL_LIMIT] = self.vel_limit_rad_s
        fw[L.F_OVERSPEED] = self.overspeed_ratio
        fw[L.F_INT_DECAY] = self.integrator_decay
        fw[L.F_CUR_KP] = self.cur_kp_v_a
        fw[L.F_CUR_KI] = self.cur_ki_v_as
        fw[L.F_CUR_LIMIT] = self.current_limit_a
        fw[L.F_V_LIMIT] = self.max_duty * self.supply_v
        return phys, fw


_NON_NEGATIVE = (
    "motor_viscous_nms",
    "motor_coulomb_nm",
    "motor_stribeck_rad_s",
    "inductance_h",
    "play_rad",
    "gear_damping_nms",
    "load_viscous_nms",
    "load_coulomb_nm",
    "load_stribeck_rad_s",
    "load_mass_kg",
    "load_arm_m",
    "motor_encoder_noise_counts",
    "load_encoder_noise_counts",
    "velocity_filter_s",
    "pll_bandwidth_rad_s",
    "pos_p",
    "pos_i",
    "pos_d",
    "p_scale",
    "i_scale",
    "d_scale",
    "output_limit",
    "deadband_counts",
    "min_output",
    "pos_kv_1_s",
    "vel_kp_a_rad_s",
    "vel_ki_a_rad",
    "cur_kp_v_a",
    "cur_ki_v_as",
)
_POSITIVE = (
    "supply_v",
    "motor_inertia_kgm2",
    "torque_constant_nm_a",
    "back_emf_v_s",
    "resistance_ohm",
    "gear_ratio",
    "gear_stiffness_nm_rad",
    "load_inertia_kgm2",
    "control_rate_hz",
    "current_rate_hz",
    "output_full_scale",
)
_POSITIVE_OR_INF = ("range_rad", "vel_limit_rad_s", "overspeed_ratio", "current_limit_a")
_TEXT = ("name", "description", "loop_encoder", "output_encoder", "firmware")
_INTEGERS = ("motor_encoder_cpr", "load_encoder_cpr", "substeps")
# The explicit sub-step is stable while h * omega < 2; these bounds keep it accurate too.
_MAX_OMEGA_H = 0.5
_MAX_RATE_H = 0.5


def _validate(p: TwinParams) -> None:
    """Check every field; raise a one-line ConfigError naming the first bad value."""
    for name in _TEXT:
        if not isinstance(getattr(p, name), str):
            raise ConfigError(f"{name} (={getattr(p, name)!r}) must be text")
    for name in _INTEGERS:
        validation.integer(name, getattr(p, name), minimum=0)
    for name in _NON_NEGATIVE:
        validation.non_negative(name, getattr(p, name))
    for name in _POSITIVE:
        validation.positive(name, getattr(p, name))
    for name in _POSITIVE_OR_INF:
        value = getattr(p, name)
        if (
            not (isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool))
            or not value > 0
        ):
            raise ConfigError(f"{name} (={validation.show(value)}) must be > 0 (inf for no limit)")
    _choice("firmware", p.firmware, FIRMWARES)
    _choice("loop_encoder", p.loop_encoder, ENCODER_SIDES)
    _choice("output_encoder", p.output_encoder, ENCODER_SIDES)
    validation.in_unit_interval("max_duty", p.max_duty, open_low=True, open_high=False)
    validation.in_unit_interval("gear_efficiency", p.gear_efficiency, open_low=True, open_high=False)
    validation.in_unit_interval("integrator_decay", p.integrator_decay, open_low=True, open_high=False)
    if p.motor_breakaway_nm < p.motor_coulomb_nm:
        raise ConfigError(
            f"motor_breakaway_nm (={p.motor_breakaway_nm!r}) must be >= motor_coulomb_nm (={p.motor_coulomb_nm!r})"
        )
    if p.load_breakaway_nm < p.load_coulomb_nm:
        raise ConfigError(
            f"load_breakaway_nm (={p.load_breakaway_nm!r}) must be >= load_coulomb_nm (={p.load_coulomb_nm!r})"
        )
    if p.play_rad >= p.range_rad:
        raise ConfigError(f"play_rad (={p.play_rad!r}) must be smaller than the range range_rad (={p.range_rad!r})")
    for side in ENCODER_SIDES:
        cpr = p.motor_encoder_cpr if side == "motor" else p.load_encoder_cpr
        for role in ("loop_encoder", "output_encoder"):
            if getattr(p, role) == side and cpr == 0:
                raise ConfigError(f"{role} (={side!r}) needs a {side} encoder: {side}_encoder_cpr is 0")
    if p.substeps < 1:
        raise ConfigError(f"substeps (={p.substeps!r}) must be >= 1")
    ratio = p.current_rate_hz / p.control_rate_hz
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise ConfigError(
            f"current_rate_hz (={p.current_rate_hz!r}) must be a whole multiple of control_rate_hz (={p.control_rate_hz!r})"
        )
    _check_substep(p)


def _choice(name: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ConfigError(f"{name} (={value!r}) must be one of {', '.join(allowed)}")


def _check_substep(p: TwinParams) -> None:
    """Refuse parameters the fixed sub-step cannot integrate faithfully (a stiff gear on a tiny load...)."""
    h = p.substep_s
    reflected = p.motor_inertia_kgm2 * p.gear_ratio**2
    j_eff = reflected * p.load_inertia_kgm2 / (reflected + p.load_inertia_kgm2)
    omega = math.sqrt(p.gear_stiffness_nm_rad / j_eff)
    if omega * h > _MAX_OMEGA_H:
        raise ConfigError(
            f"gear_stiffness_nm_rad (={p.gear_stiffness_nm_rad!r}) with load_inertia_kgm2 (={p.load_inertia_kgm2!r}) "
            f"rings at {omega:.4g} rad/s, too fast for the sub-step of {h * 1e6:.3g} us: raise substeps "
            f"to >= {math.ceil(p.substeps * omega * h / _MAX_OMEGA_H)}"
        )
    rates = {
        "gear_damping_nms": p.gear_damping_nms / j_eff,
        "load_viscous_nms": p.load_viscous_nms / p.load_inertia_kgm2,
        "motor_viscous_nms": (p.motor_viscous_nms + p.torque_constant_nm_a * p.back_emf_v_s / p.resistance_ohm)
        / p.motor_inertia_kgm2,
    }
    for name, rate in rates.items():
        if rate * h > _MAX_RATE_H:
            raise ConfigError(
                f"{name} (={getattr(p, name)!r}) damps at {rate:.4g} 1/s, too fast for the sub-step of "
                f"{h * 1e6:.3g} us: raise substeps to >= {math.ceil(p.substeps * rate * h / _MAX_RATE_H)}"
            )


def override(params: TwinParams, **overrides: Any) -> TwinParams:
    """``params`` with parameters replaced by name (aliases and text values allowed).

    Parameters
    ----------
    params : TwinParams
        The starting point (a preset).
    **overrides
        ``name=value`` pairs: any field of :class:`TwinParams`, or an alias of
        :data:`ALIASES` (``play_deg=0.8``), or ``encoder_noise_counts`` (the
        output encoder's noise). Values may be text (from a URL).

    Raises
    ------
    ConfigError
        For an unknown name or a value that is not a number (or is out of range).
    """
    fields = {f.name: f for f in dataclasses.fields(TwinParams)}
    allowed = set(fields) | set(ALIASES) | {"encoder_noise_counts"}
    validation.reject_unknown("twin parameter", overrides, allowed)
    changes: dict[str, Any] = {}
    for name, value in overrides.items():
        target, factor = ALIASES.get(name, (name, 1.0))
        if name == "encoder_noise_counts":
            target = f"{params.output_encoder}_encoder_noise_counts"
        kind = fields[target].type
        if kind in ("str", str):
            changes[target] = str(value)
        elif target in _INTEGERS:
            changes[target] = _parse(name, value, whole=True)
        else:
            changes[target] = _parse(name, value, whole=False) * factor
    return dataclasses.replace(params, **changes)


def _parse(name: str, value: Any, whole: bool) -> float | int:
    """A number from code or from a URL's text; ``whole``: a count (int >= 0)."""
    if isinstance(value, str):
        try:
            value = int(value) if whole else float(value)
        except ValueError:
            raise ConfigError(f"{name} (={value!r}) must be a {'whole number' if whole else 'number'}") from None
    if whole:
        return validation.integer(name, value, minimum=0)
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or math.isnan(value):
        raise ConfigError(f"{name} (={validation.show(value)}) must be a number")
    return float(value)
