"""The servos we measure against, with the source of every number.

Four presets (:func:`preset`): ``xm430`` (ROBOTIS Dynamixel XM430-W350,
12 V), ``sts3215`` (Feetech STS3215, 7.4 V version), ``cia402`` (an
industrial CiA 402 drive with a motor and a load encoder through a
planetary gear) and ``odrive`` (ODrive v3.6 with a D5065-class motor, a
reducer and a load encoder).

Sources, as cited in the comments below:

[XM]   ROBOTIS e-manual, XM430-W350 page (github.com/ROBOTIS-GIT/emanual,
       docs/en/dxl/x/xm430-w350.md): specifications and control table.
[XPID] ROBOTIS e-manual, "Position PID Gain" (same repository,
       _includes/dxl/control_table_position_pid_gain.md): conversions and the
       Position Control Mode block diagram (PID + feedforward -> PWM limit -> inverter).
[XH]   ROBOTIS e-manual, XH430-V350 page: "Backlash 15 arcmin (0.25 deg)", same
       353.5:1 metal gear train as the XM430-W350.
[RW]   ROBOTIS, DynamixelSDK issue #534: the control loop rate is not disclosed,
       "much faster than 1 kHz".
[ST]   STS/ST3215 memory table (as exported in the ``st3215`` Rust crate, build.rs /
       register docs): P 32, D 32, I 0, minimum startup force 16 (0.1 %), CW/CCW
       insensitive zone 1 step, maximum torque 1000 (0.1 %), max input voltage 8.0 V
       (the 7.4 V version).
[STD]  ST3215 product data (DFRobot SER0069 listing): 19.5 kg cm stall torque at
       7.4 V, 0.192 s/60 deg (52 rpm) no-load at 7.4 V, 150 mA no-load current at
       7.4 V, 1:345 gear, 12-bit magnetic encoder (4096 steps).
[STB]  Feetech's backlash figure <= 0.5 deg (spec, quoted by robonine.com's STS3215
       test); TheRobotStudio/SO-ARM100 issue #134 measured about 1 deg of free play
       on the 12 V STS3215.
[S50]  Feetech STS3250 spec sheet as tabled by robonine.com: "position update rate
       1 ms" (the same firmware family).
[EP]   maxon EPOS4 50/5 hardware reference (rel6852, section 2.1): 10-50 V supply,
       output voltage max 0.9 Vcc, 5 A continuous / 15 A peak, current PI at 25 kHz,
       speed and position PID at 2.5 kHz.
[RE]   maxon RE 65 (48 V, variant 353297) catalogue data (as quoted at
       pastebin.com/7kFwyXJK): terminal resistance 0.365 ohm, inductance 0.161 mH,
       torque constant 123 mNm/A, speed constant 77.8 rpm/V, rotor inertia
       1340 g cm^2, no-load speed 3670 rpm at 289 mA, max. speed 5500 rpm.
[NP]   Beckhoff AG3210-NP035 planetary gear (infosys.beckhoff.com, ag3210_ba):
       1 stage, i = 3..10, efficiency 97 %, torsional backlash <= 8 arcmin
       (standard), torsional rigidity 22 Nm/arcmin, input inertia 0.90 kg cm^2 and
       up, no-load running torque 0.58 Nm at i = 10.
[OD]   ODrive firmware 0.5.x, Firmware/MotorControl/controller.hpp: pos_gain 20
       (turn/s)/turn, vel_gain 1/6 Nm/(turn/s), vel_integrator_gain 2/6
       Nm/(turn/s s), vel_limit 2 turn/s, vel_limit_tolerance 1.2; controller.cpp:
       velocity command clipped at vel_limit, integrator x 0.99 while the torque is
       limited, overspeed error beyond tolerance x limit; motor.cpp: current PI
       p_gain = bw L, i_gain = bw R with current_control_bandwidth 1000 rad/s,
       modulation limited to 0.8 sqrt(3)/2 with mod = Vq / (2/3 Vbus), integrator
       x 0.99 while saturated; docs/control.rst: loops at 8 kHz; getting-started:
       torque_constant = 8.27 / KV, AMT102 encoder cpr = 8192, current_lim 10 A,
       encoder PLL bandwidth 1000 rad/s.

"assumed" marks a number no source we could check gives; the comment says
why the value is plausible. Derived numbers are computed here from the
sourced ones, so a reader sees the arithmetic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from servoid.drivers.twin.params import TwinParams, override
from servoid.errors import ConfigError

__all__ = ["preset", "preset_names", "PRESETS", "Published", "PUBLISHED"]

_RPM = 2.0 * math.pi / 60.0  # rad/s per rpm
_KGCM = 0.0980665  # N m per kg cm

# ---------------------------------------------------------------------------
# ROBOTIS Dynamixel XM430-W350, 12 V
# ---------------------------------------------------------------------------
_XM_V = 12.0  # recommended input voltage [XM]
_XM_N = 353.5  # gear ratio [XM]
_XM_STALL_NM, _XM_STALL_A = 4.1, 2.3  # stall torque 4.1 N m at 12.0 V, 2.3 A [XM]
_XM_NOLOAD_W = 46.0 * _RPM  # no-load speed 46 rpm at 12.0 V [XM], output rad/s
# assumed: the e-manual gives only the standby current (40 mA); 150 mA is what the
# STS3215, a servo of the same size and gear class, draws at no load [STD]
_XM_NOLOAD_A = 0.15
_XM_R = _XM_V / _XM_STALL_A  # derived: the stall point at full duty, winding + bridge
_XM_KE = (_XM_V - _XM_R * _XM_NOLOAD_A) / (_XM_NOLOAD_W * _XM_N)  # derived from the no-load point
_XM_FRICTION = _XM_KE * _XM_NOLOAD_A  # motor-side friction torque at no-load speed (derived)
_FRICTION_COULOMB_SHARE = 0.5  # assumed: half of the no-load friction is Coulomb, half viscous
# derived: the stall torque is what passes the gear while the motor pushes against its Coulomb friction
_XM_ETA = _XM_STALL_NM / (_XM_N * (_XM_KE * _XM_STALL_A - _FRICTION_COULOMB_SHARE * _XM_FRICTION))

XM430 = TwinParams(
    name="xm430",
    description="ROBOTIS Dynamixel XM430-W350 at 12 V, Position Control Mode, factory gains",
    supply_v=_XM_V,
    max_duty=1.0,  # PWM Limit 885 = 100 % [XM], the firmware's limit is below
    # assumed: rotor of a 16-17 mm coreless DC motor is 0.5-1 g cm^2 (maxon DCX 16 class)
    motor_inertia_kgm2=6e-8,
    motor_viscous_nms=(1.0 - _FRICTION_COULOMB_SHARE) * _XM_FRICTION / (_XM_NOLOAD_W * _XM_N),
    motor_coulomb_nm=_FRICTION_COULOMB_SHARE * _XM_FRICTION,
    # assumed: break-away 1.5 x Coulomb, usual for greased spur trains
    motor_breakaway_nm=1.5 * _FRICTION_COULOMB_SHARE * _XM_FRICTION,
    motor_stribeck_rad_s=10.0,  # assumed: the hump fades over ~100 rpm of the motor
    torque_constant_nm_a=_XM_KE,  # SI: Kt = Ke
    back_emf_v_s=_XM_KE,
    resistance_ohm=_XM_R,
    inductance_h=0.25e-3,  # assumed: 0.1-0.5 mH is typical of small coreless windings; L/R = 48 us
    gear_ratio=_XM_N,
    play_rad=math.radians(0.25),  # 15 arcmin [XH], same gear train
    # assumed: 1.2 deg of wind-up at the stall torque, typical of a small metal spur train and horn
    gear_stiffness_nm_rad=200.0,
    gear_damping_nms=0.04,  # assumed: about 10 % of critical with the default load
    gear_efficiency=_XM_ETA,
    # assumed bench load: a 100 g mass on a 50 mm arm, horizontal (no gravity)
    load_inertia_kgm2=2.5e-4,
    load_viscous_nms=1e-4,  # assumed: horn bearing
    load_coulomb_nm=0.005,  # assumed: horn bearing, small against the 4.1 N m stall torque
    load_breakaway_nm=0.006,
    load_stribeck_rad_s=0.05,
    motor_encoder_cpr=0,  # no motor encoder
    load_encoder_cpr=4096,  # AS5045, 12 bit, 4096 pulse/rev, on the horn [XM]
    loop_encoder="load",
    output_encoder="load",
    firmware="dynamixel_position",  # Position Control Mode, Operating Mode 3 (default) [XM], diagram [XPID]
    control_rate_hz=4000.0,  # assumed: not disclosed, "much faster than 1 kHz" [RW]
    current_rate_hz=4000.0,  # no current loop in Position Control Mode [XPID]
    substeps=10,  # 25 us
    range_rad=2.0 * math.pi,  # Min/Max Position Limit 0..4095: one turn [XM]
    velocity_filter_s=0.01,  # assumed: Present Velocity is a filtered estimate; the filter is not published
    pos_p=800.0,  # Position P Gain (84) initial value [XM]
    pos_i=0.0,  # Position I Gain (82) [XM]
    pos_d=0.0,  # Position D Gain (80) [XM]
    p_scale=1.0 / 128.0,  # KPP = P / 128 [XPID]
    i_scale=1.0 / 65536.0,  # KPI = I / 65536 [XPID]
    d_scale=1.0 / 16.0,  # KPD = D / 16 [XPID]
    output_limit=885.0,  # PWM Limit (36) initial value [XM]
    output_full_scale=885.0,  # 885 = 100 % [XM]
)

# ---------------------------------------------------------------------------
# Feetech STS3215, 7.4 V version
# ---------------------------------------------------------------------------
_ST_V = 7.4  # [STD]; the memory table's max input voltage 8.0 V marks the 7.4 V version [ST]
_ST_N = 345.0  # [STD]
_ST_STALL_NM = 19.5 * _KGCM  # 19.5 kg cm at 7.4 V [STD]
_ST_NOLOAD_W = (60.0 / 0.192) * math.pi / 180.0  # 0.192 s / 60 deg at 7.4 V [STD], output rad/s
_ST_NOLOAD_A = 0.15  # 150 mA at 7.4 V [STD]
_ST_ETA = _XM_ETA  # assumed: the same class of multi-stage metal spur train as the XM430


def _stall_resistance(v: float, stall_nm: float, noload_w: float, noload_a: float, eta: float) -> float:
    """The resistance that makes a motor meet its stall torque and no-load point (both published).

    With ``Ke = (V - R I0) / (N w0)`` (the no-load point) and the stall torque
    ``T = eta N (Ke V / R - c Ke I0)`` (c: the Coulomb share of the no-load
    friction), ``T R = eta N Ke (V - c I0 R)`` is a quadratic in ``R``; the
    physical root is the smaller one (``R < V / I0``).
    """
    k = eta / noload_w
    c = _FRICTION_COULOMB_SHARE
    a2 = k * c * noload_a**2
    a1 = -(k * v * noload_a * (1.0 + c) + stall_nm)
    a0 = k * v**2
    return (-a1 - math.sqrt(a1 * a1 - 4.0 * a2 * a0)) / (2.0 * a2)


# derived: the stall current is not published; R from the stall torque and the no-load point
_ST_R = _stall_resistance(_ST_V, _ST_STALL_NM, _ST_NOLOAD_W, _ST_NOLOAD_A, _ST_ETA)
_ST_KE = (_ST_V - _ST_R * _ST_NOLOAD_A) / (_ST_NOLOAD_W * _ST_N)
_ST_FRICTION = _ST_KE * _ST_NOLOAD_A

STS3215 = TwinParams(
    name="sts3215",
    description="Feetech STS3215 (7.4 V version), position servo mode, factory memory table",
    supply_v=_ST_V,
    max_duty=1.0,  # maximum torque 1000 = 100 % [ST]
    motor_inertia_kgm2=8e-8,  # assumed: a slightly larger motor than the XM430's in a similar case
    motor_viscous_nms=(1.0 - _FRICTION_COULOMB_SHARE) * _ST_FRICTION / (_ST_NOLOAD_W * _ST_N),  # split as for the XM430
    motor_coulomb_nm=_FRICTION_COULOMB_SHARE * _ST_FRICTION,
    motor_breakaway_nm=1.5 * _FRICTION_COULOMB_SHARE * _ST_FRICTION,  # assumed: 1.5 x Coulomb
    motor_stribeck_rad_s=10.0,  # assumed
    torque_constant_nm_a=_ST_KE,
    back_emf_v_s=_ST_KE,
    resistance_ohm=_ST_R,  # derived (about 3.7 ohm: a stall current of about 2 A)
    inductance_h=0.2e-3,  # assumed: small DC motor winding
    gear_ratio=_ST_N,
    # 0.6 deg: between the spec's <= 0.5 deg and the ~1 deg measured on a 12 V unit [STB]
    play_rad=math.radians(0.6),
    gear_stiffness_nm_rad=150.0,  # assumed: 0.7 deg wind-up at the stall torque (brass/aluminium gears)
    gear_damping_nms=0.03,  # assumed: about 10 % of critical with the default load
    gear_efficiency=_ST_ETA,
    load_inertia_kgm2=2.5e-4,  # assumed bench load, as for the XM430
    load_viscous_nms=1e-4,
    load_coulomb_nm=0.005,
    load_breakaway_nm=0.006,
    load_stribeck_rad_s=0.05,
    motor_encoder_cpr=0,
    load_encoder_cpr=4096,  # 12-bit magnetic encoder, 4096 steps [STD]
    loop_encoder="load",
    output_encoder="load",
    firmware="feetech_position",  # operation mode 0: position servo mode [ST]
    control_rate_hz=1000.0,  # "position update rate 1 ms" [S50] (assumed to be the loop rate)
    current_rate_hz=1000.0,  # no current loop
    substeps=40,  # 25 us
    range_rad=2.0 * math.pi,  # angle limits 0..4095 [ST]
    velocity_filter_s=0.01,  # assumed, as for the XM430
    pos_p=32.0,  # P coefficient (21) [ST]
    pos_i=0.0,  # I coefficient (23) [ST]
    pos_d=32.0,  # D coefficient (22) [ST]
    # assumed: Feetech does not publish the coefficients' units. 1/4 per unit gives
    # P = 32 -> 8 per mille of duty per count, the XM430's factory stiffness (7 per mille)
    p_scale=0.25,
    i_scale=1.0 / 256.0,
    d_scale=0.25,
    output_limit=1000.0,  # maximum torque (16) / torque limit (48): 1000 = 100 % [ST]
    output_full_scale=1000.0,
    deadband_counts=1.0,  # CW / CCW insensitive zone (26, 27): 1 step [ST]
    min_output=16.0,  # minimum startup force (24): 16 = 1.6 % [ST]
)

# ---------------------------------------------------------------------------
# Industrial CiA 402 drive: maxon EPOS4 50/5 + RE 65 + one-stage planetary i = 10
# ---------------------------------------------------------------------------
_IN_N = 10.0  # [NP] (one stage, i = 10)
_IN_J_M = 1340e-7 + 0.90e-4  # rotor 1340 g cm^2 [RE] + gear input 0.90 kg cm^2 [NP]
_IN_KT = 0.123  # [RE]
_IN_J_L = 0.02  # assumed load: a short link and payload, 0.02 kg m^2 (about 1.4 kg at 120 mm)
_IN_NOLOAD_W = 3670.0 * _RPM  # [RE]
_IN_MOTOR_FRICTION = _IN_KT * 0.289  # no-load current 289 mA [RE]
_IN_GEAR_RUNNING = 0.58  # no-load running torque at i = 10 [NP], at the input
_IN_GEAR_W = 2800.0 * _RPM  # assumed: the running torque holds at the gear's mean input speed
_IN_J_TOTAL = _IN_J_M + _IN_J_L / _IN_N**2  # motor-side inertia the velocity loop sees
_IN_CUR_BW = 2.0 * math.pi * 1000.0  # assumed tuning: 1 kHz current loop (25 kHz sampling [EP])
_IN_VEL_BW = 2.0 * math.pi * 40.0  # assumed tuning: 40 Hz velocity loop (2.5 kHz sampling [EP])
_IN_K = 22.0 * 10800.0 / math.pi  # 22 Nm/arcmin [NP] in N m/rad

CIA402 = TwinParams(
    name="cia402",
    description="industrial CiA 402 drive (maxon EPOS4 50/5, RE 65 motor, planetary i=10, load encoder)",
    supply_v=48.0,  # [RE] nominal voltage, within the EPOS4's 10-50 V [EP]
    max_duty=0.9,  # output voltage max 0.9 x Vcc [EP]
    motor_inertia_kgm2=_IN_J_M,
    # motor: its no-load friction split half and half (assumed); gear: its running torque
    # taken 85 % viscous (churning), 15 % Coulomb (assumed split)
    motor_viscous_nms=0.5 * _IN_MOTOR_FRICTION / _IN_NOLOAD_W + 0.85 * _IN_GEAR_RUNNING / _IN_GEAR_W,
    motor_coulomb_nm=0.5 * _IN_MOTOR_FRICTION + 0.15 * _IN_GEAR_RUNNING,
    motor_breakaway_nm=1.3 * (0.5 * _IN_MOTOR_FRICTION + 0.15 * _IN_GEAR_RUNNING),  # assumed 1.3 x
    motor_stribeck_rad_s=1.0,  # assumed
    torque_constant_nm_a=_IN_KT,
    back_emf_v_s=60.0 / (2.0 * math.pi * 77.8),  # speed constant 77.8 rpm/V [RE]
    resistance_ohm=0.365,  # [RE]
    inductance_h=0.161e-3,  # [RE]
    gear_ratio=_IN_N,
    play_rad=math.radians(8.0 / 60.0),  # <= 8 arcmin, standard backlash [NP]
    gear_stiffness_nm_rad=_IN_K,
    gear_damping_nms=2.8,  # assumed: about 5 % of critical with the default load
    gear_efficiency=0.97,  # [NP]
    load_inertia_kgm2=_IN_J_L,
    load_viscous_nms=0.01,  # assumed: output bearings and seal
    load_coulomb_nm=0.2,  # assumed: output bearings and seal
    load_breakaway_nm=0.25,
    load_stribeck_rad_s=0.01,
    motor_encoder_cpr=2**17,  # assumed: 17-bit absolute motor encoder, common on industrial servo motors
    load_encoder_cpr=2**20,  # assumed: 20-bit absolute encoder on the output
    loop_encoder="motor",
    output_encoder="load",
    firmware="cascade",
    control_rate_hz=2500.0,  # speed and position controllers at 2.5 kHz [EP]
    current_rate_hz=25000.0,  # PI current controller at 25 kHz [EP]
    substeps=2,  # 20 us
    range_rad=2.0 * math.pi,  # assumed: software position limits of +-180 deg at the output
    velocity_filter_s=1e-3,  # assumed: the velocity from encoder differences through a 1 ms filter
    pos_kv_1_s=_IN_VEL_BW / 4.0,  # assumed tuning: position bandwidth a quarter of the velocity loop's
    vel_kp_a_rad_s=_IN_J_TOTAL * _IN_VEL_BW / _IN_KT,  # assumed tuning (the autotuner's target)
    vel_ki_a_rad=_IN_J_TOTAL * _IN_VEL_BW / _IN_KT * _IN_VEL_BW / 4.0,  # PI zero at a quarter of it
    vel_limit_rad_s=5500.0 * _RPM,  # max. speed 5500 rpm [RE], the drive's max profile velocity
    integrator_decay=1.0,  # conditional integration (assumed)
    cur_kp_v_a=0.161e-3 * _IN_CUR_BW,  # L x bandwidth
    cur_ki_v_as=0.365 * _IN_CUR_BW,  # R x bandwidth: the PI zero cancels the winding's pole
    current_limit_a=15.0,  # peak 15 A [EP]
)

# ---------------------------------------------------------------------------
# ODrive v3.6 (24 V) + D5065 270 KV + reducer + load encoder
# ---------------------------------------------------------------------------
_OD_KT = 8.27 / 270.0  # torque_constant = 8.27 / KV [OD], KV 270 (D5065 270KV)
_OD_R_PHASE = 0.039  # assumed: ODrive's calibration reports tens of milliohm on 50xx outrunners
_OD_L_PHASE = 20e-6  # assumed: tens of microhenry, same class
_OD_BW = 1000.0  # current_control_bandwidth 1000 rad/s [OD]
_OD_TURN = 2.0 * math.pi  # ODrive's units are turns of the motor

ODRIVE = TwinParams(
    name="odrive",
    description="ODrive v3.6 (24 V) with a D5065 270 KV motor, 8:1 reducer, AMT102 motor and AS5047P load encoders",
    supply_v=24.0,  # the 24 V board
    # modulation limit 0.8 sqrt(3)/2 of mod = Vq / (2/3 Vbus) [OD]: Vq <= 0.8 Vbus / sqrt(3);
    # in the power-invariant DC equivalent (x 1.5) that is 0.8 sqrt(3)/2 of Vbus
    max_duty=0.8 * math.sqrt(3.0) / 2.0,
    motor_inertia_kgm2=1.1e-4,  # assumed: a 50 mm outrunner bell of about 200 g at 24 mm radius
    motor_viscous_nms=2e-5,  # assumed: bearings and iron losses
    motor_coulomb_nm=0.01,  # assumed: bearings and averaged cogging
    motor_breakaway_nm=0.015,  # assumed: 1.5 x
    motor_stribeck_rad_s=2.0,
    torque_constant_nm_a=_OD_KT,
    back_emf_v_s=_OD_KT,  # DC equivalent of the q axis (see servoid.drivers.twin.params)
    resistance_ohm=1.5 * _OD_R_PHASE,
    inductance_h=1.5 * _OD_L_PHASE,
    gear_ratio=8.0,  # assumed: a common 8:1 belt or planetary stage on ODrive robot joints
    play_rad=math.radians(0.3),  # assumed: 18 arcmin, a hobby-grade planetary or belt stage
    gear_stiffness_nm_rad=800.0,  # assumed
    gear_damping_nms=0.2,  # assumed: about 5 % of critical with the default load
    gear_efficiency=0.9,  # assumed
    load_inertia_kgm2=0.02,  # assumed load, as for the CiA 402 preset
    load_viscous_nms=0.005,
    load_coulomb_nm=0.05,
    load_breakaway_nm=0.06,
    load_stribeck_rad_s=0.01,
    motor_encoder_cpr=8192,  # AMT102 at 2048 PPR: cpr = 8192 [OD]
    load_encoder_cpr=16384,  # AS5047P, 14 bit (assumed choice of load encoder)
    loop_encoder="motor",  # the default: the axis's own encoder [OD]
    output_encoder="load",
    firmware="cascade",
    control_rate_hz=8000.0,  # 8 kHz [OD]
    current_rate_hz=8000.0,  # current control in the same 8 kHz loop [OD]
    substeps=8,  # 15.6 us
    range_rad=math.inf,  # no position limit by default
    pll_bandwidth_rad_s=1000.0,  # encoder bandwidth 1000 rad/s [OD]
    pos_kv_1_s=20.0,  # pos_gain 20 (turn/s)/turn [OD]
    vel_kp_a_rad_s=(1.0 / 6.0) / _OD_TURN / _OD_KT,  # vel_gain 1/6 Nm/(turn/s) [OD] -> A per rad/s
    vel_ki_a_rad=(2.0 / 6.0) / _OD_TURN / _OD_KT,  # vel_integrator_gain 2/6 Nm/(turn/s s) [OD]
    vel_limit_rad_s=2.0 * _OD_TURN,  # vel_limit 2 turn/s [OD]
    overspeed_ratio=1.2,  # vel_limit_tolerance 1.2 [OD]
    integrator_decay=0.99,  # [OD]
    cur_kp_v_a=_OD_BW * 1.5 * _OD_L_PHASE,  # p_gain = bw L [OD], DC equivalent
    cur_ki_v_as=_OD_BW * 1.5 * _OD_R_PHASE,  # i_gain = bw R [OD], DC equivalent
    current_limit_a=10.0,  # current_lim 10 A [OD]
)

#: The presets by name.
PRESETS: dict[str, TwinParams] = {p.name: p for p in (XM430, STS3215, CIA402, ODRIVE)}


@dataclass(frozen=True)
class Published:
    """A servo's figures as its vendor publishes them (None: not published for this assembly).

    Attributes
    ----------
    no_load_speed_rpm : float or None
        Output speed without load at the preset's supply voltage, rpm.
    stall_torque_nm : float or None
        Output torque with the output held, N m.
    stall_current_a : float or None
        Current meanwhile, A.
    output_cpr : int or None
        Counts per output revolution of the output encoder.
    source : str
        Where the figures come from (the keys of this module's docstring).
    """

    no_load_speed_rpm: float | None
    stall_torque_nm: float | None
    stall_current_a: float | None
    output_cpr: int | None
    source: str


#: What the vendors publish, to hold the twins against (:mod:`servoid.drivers.twin.figures`).
PUBLISHED: dict[str, Published] = {
    "xm430": Published(46.0, _XM_STALL_NM, _XM_STALL_A, 4096, "[XM]"),
    "sts3215": Published(_ST_NOLOAD_W * 60.0 / (2.0 * math.pi), _ST_STALL_NM, None, 4096, "[STD]"),
    # assembled from parts: the motor's and drive's figures apply to the parts, not to the servo
    "cia402": Published(None, None, None, None, "[EP], [RE], [NP]"),
    "odrive": Published(None, None, None, None, "[OD]"),
}


def preset_names() -> tuple[str, ...]:
    """The names :func:`preset` accepts."""
    return tuple(PRESETS)


def preset(name: str, **overrides: Any) -> TwinParams:
    """A preset's parameters, with any of them overridden by name.

    Parameters
    ----------
    name : str
        ``"xm430"``, ``"sts3215"``, ``"cia402"`` or ``"odrive"``.
    **overrides
        Any :class:`~servoid.drivers.twin.params.TwinParams` field or alias
        (``play_deg=0.8``, ``load_inertia_kgm2=1e-3``,
        ``encoder_noise_counts=0.5``); text values are parsed.

    Returns
    -------
    TwinParams

    Raises
    ------
    ConfigError
        For an unknown preset or parameter, or a bad value (one line, naming it).
    """
    key = name.strip().lower() if isinstance(name, str) else name
    if key not in PRESETS:
        raise ConfigError(f"unknown twin preset {name!r}; valid: {', '.join(PRESETS)}")
    base = PRESETS[key]
    return override(base, **overrides) if overrides else base
