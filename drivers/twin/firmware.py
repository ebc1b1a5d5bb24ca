"""The drives' control loops, one tick at a time, on quantised encoder counts (compiled).

A drive samples its encoders and runs its loops at its own rate; between
ticks its output (a PWM duty, or a voltage from a current loop) is held.
Three structures, each as the vendor draws it:

``dynamixel_position``
    ROBOTIS X series, Position Control Mode (e-manual, "Position PID Gain"):
    the Goal Position, in counts of the horn encoder, minus the Present
    Position gives the error; ``PWM = KPP e + KPI sum(e) + KPD (e - e_prev)``
    with ``KPP = P/128``, ``KPI = I/65536``, ``KPD = D/16`` (the constants
    include the sampling time); the PWM is clipped at the PWM Limit (885 =
    100 % duty) and drives the motor through the inverter. There is no
    velocity or current loop in this mode. Profile Velocity and Acceleration
    are 0 (the defaults): no trajectory, so the feedforward terms see none
    and are not modelled. The anti-windup gain ``Ka`` is not published;
    the twin integrates conditionally (not while the output is saturated in
    the error's direction).
``feetech_position``
    Feetech STS, position servo mode: a PID on the horn encoder's counts
    with the memory table's P/D/I coefficients, an insensitive zone
    (CW/CCW dead band, counts) inside which the output is off, a minimum
    output ("minimum startup force") outside it, and the torque limit
    (1000 = 100 % duty). Feetech does not publish the gains' units: the
    scales are the preset's (documented there as assumed).
``cascade``
    Industrial CiA 402 drives and the ODrive: position P -> velocity PI ->
    current PI -> voltage, closed on the motor (or load) encoder. The
    velocity command is clipped at the velocity limit, the current command
    at the current limit, the voltage at the output stage's limit; a
    saturated integrator decays by ``integrator_decay`` per tick (ODrive:
    0.99) or, with 1, holds. With a PLL bandwidth the position and velocity
    come from an encoder PLL (ODrive's ``encoder.config.bandwidth``:
    ``kp = 2 bw``, ``ki = bw^2 / 4``, on counts); otherwise the velocity is
    the encoder's difference per tick through a first-order filter. An
    ODrive faults (output stage off) when the velocity estimate exceeds
    ``overspeed_ratio`` times the velocity limit.

    In torque mode (CiA 402 cyclic synchronous torque, ODrive torque
    control) the set point is the motor torque: the current command is
    ``torque / Kt``, limited, as ODrive's ``enable_torque_mode_vel_limit``
    does (its default), so that the speed stays below the velocity limit
    (``(+-vel_limit - vel) * vel_gain``; assumed for the CiA 402 drive too),
    and clipped at the current limit; the position and velocity loops are
    idle.

At a control tick the drive, in this order: samples both encoders (with
noise), latches the host's pending set point (sample-and-hold: a command
that arrives between ticks waits for the next one), clips it to the travel,
estimates velocity, and computes its output. It also refreshes the
registers a host reads (encoder counts, velocity, current, duty).
"""

from __future__ import annotations

import math

import numpy as np

from servoid.drivers.twin import _layout as L
from servoid.drivers.twin._jit import jit
from servoid.drivers.twin.encoder import quantise

__all__ = ["control_tick", "current_tick"]

_TWO_PI = 2.0 * math.pi


@jit
def _clip(x: float, limit: float) -> float:
    if x > limit:
        return limit
    if x < -limit:
        return -limit
    return x


@jit
def control_tick(
    phys: np.ndarray, fw: np.ndarray, state: np.ndarray, mem: np.ndarray, noise_m: float, noise_l: float
) -> None:
    """Run one control tick: sample, latch, estimate, control; refresh the registers.

    Parameters
    ----------
    phys, fw : numpy.ndarray
        The twin's constants (:mod:`servoid.drivers.twin._layout`).
    state, mem : numpy.ndarray
        The twin's state and the firmware's memory, updated in place.
    noise_m, noise_l : float
        Standard normal draws for this tick's motor and load encoder samples.
    """
    cpr_m = phys[L.P_CPR_M]
    cpr_l = phys[L.P_CPR_L]
    if cpr_m > 0.0:
        state[L.S_CNT_M] = quantise(state[L.S_TH_M], cpr_m, phys[L.P_NOISE_M] * noise_m)
    if cpr_l > 0.0:
        state[L.S_CNT_L] = quantise(state[L.S_TH_L], cpr_l, phys[L.P_NOISE_L] * noise_l)
    state[L.S_CUR] = state[L.S_I]
    state[L.S_TICK_K] = state[L.S_K]
    if state[L.S_HAS_PENDING] > 0.5:
        sp = state[L.S_PENDING]
        if state[L.S_MODE] == L.MODE_POSITION:
            if sp < fw[L.F_SP_MIN]:
                sp = fw[L.F_SP_MIN]
            elif sp > fw[L.F_SP_MAX]:
                sp = fw[L.F_SP_MAX]
        state[L.S_SP] = sp
        state[L.S_HAS_PENDING] = 0.0

    # The loop's measurement, on the loop encoder's own shaft.
    if fw[L.F_LOOP_ENC] == L.ENC_MOTOR:
        cpr = cpr_m
        counts = state[L.S_CNT_M]
        shaft_per_output = phys[L.P_N]
    else:
        cpr = cpr_l
        counts = state[L.S_CNT_L]
        shaft_per_output = 1.0
    dt = fw[L.F_DT]
    pos = counts * _TWO_PI / cpr
    if mem[L.M_FIRST] > 0.5:
        mem[L.M_POS_PREV] = pos
        mem[L.M_VEL_F] = 0.0
        mem[L.M_PLL_POS] = counts
        mem[L.M_PLL_VEL] = 0.0
        mem[L.M_FIRST] = 0.0
    bw = fw[L.F_PLL_BW]
    if bw > 0.0:
        # ODrive's encoder PLL, in counts: the phase detector compares the count with the
        # integer part of the estimate; a velocity below what one tick's correction can
        # resolve is snapped to zero.
        kp = 2.0 * bw
        ki = 0.25 * kp * kp
        p_est = mem[L.M_PLL_POS] + dt * mem[L.M_PLL_VEL]
        delta = counts - math.floor(p_est)
        p_est += dt * kp * delta
        v_est = mem[L.M_PLL_VEL] + dt * ki * delta
        if abs(v_est) < 0.5 * dt * ki:
            v_est = 0.0
        mem[L.M_PLL_POS] = p_est
        mem[L.M_PLL_VEL] = v_est
        pos_fb = p_est * _TWO_PI / cpr
        vel = v_est * _TWO_PI / cpr
    else:
        raw = (pos - mem[L.M_POS_PREV]) / dt
        tau = fw[L.F_VEL_TAU]
        if tau > 0.0:
            vel = mem[L.M_VEL_F] + (raw - mem[L.M_VEL_F]) * dt / (tau + dt)
        else:
            vel = raw
        mem[L.M_VEL_F] = vel
        pos_fb = pos
    mem[L.M_POS_PREV] = pos
    state[L.S_VEL] = vel / shaft_per_output
    state[L.S_POS_EST] = pos_fb / shaft_per_output

    if state[L.S_ENABLED] < 0.5:
        state[L.S_DUTY] = 0.0
        state[L.S_V] = 0.0
        state[L.S_I_CMD] = 0.0
        return
    state[L.S_N_TICKS] += 1.0
    kind = fw[L.F_KIND]
    vsup = phys[L.P_VSUP]
    if kind == L.FW_CASCADE:
        _cascade(fw, state, mem, pos_fb, vel, shaft_per_output, vsup, phys[L.P_KT])
        return

    # PID to PWM, in counts of the loop encoder (Dynamixel, Feetech).
    goal = math.floor(state[L.S_SP] * shaft_per_output * cpr / _TWO_PI + 0.5)
    err = goal - counts
    limit = fw[L.F_OUT_LIMIT]
    if kind == L.FW_FEETECH and abs(err) <= fw[L.F_DEADBAND]:
        out = 0.0
    else:
        summed = mem[L.M_INT] + err
        free = fw[L.F_KP] * err + fw[L.F_KI] * summed + fw[L.F_KD] * (err - mem[L.M_E_PREV])
        if kind == L.FW_FEETECH and abs(free) < fw[L.F_MIN_OUT]:
            free = math.copysign(fw[L.F_MIN_OUT], err)
        out = _clip(free, limit)
        if out == free or free * err < 0.0:
            mem[L.M_INT] = summed
    mem[L.M_E_PREV] = err
    duty = _clip(out / fw[L.F_OUT_FULL], phys[L.P_DUTY_MAX])
    if abs(out) >= limit or abs(duty) >= phys[L.P_DUTY_MAX]:
        state[L.S_N_SAT] += 1.0
    state[L.S_DUTY] = duty
    state[L.S_V] = duty * vsup


@jit
def _cascade(
    fw: np.ndarray,
    state: np.ndarray,
    mem: np.ndarray,
    pos_fb: float,
    vel: float,
    shaft_per_output: float,
    vsup: float,
    kt: float,
) -> None:
    """Position P and velocity PI of a cascade drive (or its torque mode): sets the current command."""
    vel_limit = fw[L.F_VEL_LIMIT]
    if abs(vel) > fw[L.F_OVERSPEED] * vel_limit:
        # ODrive: ERROR_OVERSPEED, the axis drops to idle (output stage off)
        state[L.S_FAULT] = L.FAULT_OVERSPEED
        state[L.S_ENABLED] = 0.0
        state[L.S_V] = 0.0
        state[L.S_I_CMD] = 0.0
        state[L.S_DUTY] = 0.0
        return
    if state[L.S_MODE] == L.MODE_TORQUE:
        # ODrive's enable_torque_mode_vel_limit: no more torque than keeps the speed below the limit
        wanted = state[L.S_SP] / kt
        high = (vel_limit - vel) * fw[L.F_VEL_KP]
        low = (-vel_limit - vel) * fw[L.F_VEL_KP]
        limited = min(max(wanted, low), high)
        i_cmd = _clip(limited, fw[L.F_CUR_LIMIT])
        if i_cmd != wanted:
            state[L.S_N_CUR_LIM] += 1.0
        state[L.S_I_CMD] = i_cmd
        if mem[L.M_SAT] > 0.5:
            state[L.S_N_SAT] += 1.0
        mem[L.M_SAT] = 0.0
        state[L.S_DUTY] = state[L.S_V] / vsup
        return
    vel_cmd = _clip(fw[L.F_POS_KV] * (state[L.S_SP] * shaft_per_output - pos_fb), vel_limit)
    v_err = vel_cmd - vel
    free = fw[L.F_VEL_KP] * v_err + mem[L.M_INT]
    i_cmd = _clip(free, fw[L.F_CUR_LIMIT])
    if i_cmd != free:
        mem[L.M_INT] *= fw[L.F_INT_DECAY]
        state[L.S_N_CUR_LIM] += 1.0
    else:
        mem[L.M_INT] += fw[L.F_VEL_KI] * fw[L.F_DT] * v_err
    state[L.S_I_CMD] = i_cmd
    if mem[L.M_SAT] > 0.5:
        state[L.S_N_SAT] += 1.0
    mem[L.M_SAT] = 0.0
    state[L.S_DUTY] = state[L.S_V] / vsup


@jit
def current_tick(phys: np.ndarray, fw: np.ndarray, state: np.ndarray, mem: np.ndarray) -> None:
    """One tick of a cascade drive's current PI: sets the terminal voltage.

    Parameters
    ----------
    phys, fw : numpy.ndarray
        The twin's constants.
    state, mem : numpy.ndarray
        State and firmware memory, updated in place.
    """
    if fw[L.F_KIND] != L.FW_CASCADE or state[L.S_ENABLED] < 0.5:
        return
    err = state[L.S_I_CMD] - state[L.S_I]
    free = fw[L.F_CUR_KP] * err + mem[L.M_CUR_INT]
    v = _clip(free, fw[L.F_V_LIMIT])
    if v != free:
        mem[L.M_CUR_INT] *= fw[L.F_INT_DECAY]
        mem[L.M_SAT] = 1.0
    else:
        mem[L.M_CUR_INT] += fw[L.F_CUR_KI] * fw[L.F_DT_C] * err
    state[L.S_V] = v
