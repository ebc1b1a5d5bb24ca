"""The twin's physics in continuous time, integrated with a fixed sub-step (compiled).

Bodies: the motor (rotor and gear input, motor-shaft angle ``theta_m``) and
the load (output angle ``theta_l``), coupled by a gear of ratio ``N`` with
a play ``b`` at the output: the gear's motor side sits at ``theta_m / N``,
and while ``|theta_m / N - theta_l| < b / 2`` no torque passes (the load
coasts on its own momentum). Past a flank the contact is a spring and
damper, ``k pen + c d(pen)/dt``, that can push but never pull. The motor
gets the contact torque back through the gear: divided by ``N * eta`` when
it drives the load (power flows out; at rest: when its torque pushes the
way the contact does), times ``eta / N`` when the load drives it -- so a
passive motor behind a lossy gear resists being back-driven, as a
high-ratio spur train does. The winding obeys ``L di/dt = V - R i - Ke w_m``, the motor
torque is ``Kt i``; the load feels gravity ``-m g l sin(theta_l)``.

Friction on each body is viscous plus Coulomb with a Stribeck hump
(``Tc + (Ts - Tc) exp(-(w/ws)^2)``) and a real stick state, after Karnopp
(1985): a stuck body stays at rest, its friction equal and opposite to the
applied torque, until that torque exceeds the break-away level ``Ts``; a
sliding body whose speed would cross zero within a sub-step stops there
and sticks, unless the applied torque exceeds ``Ts``: then it turns round
for the rest of the sub-step (so without friction momentum is exact).

Integration scheme and why: a **semi-implicit (symplectic) Euler** step of
fixed length ``h`` -- torques from the positions at the start of the step,
new velocities, then new positions from the new velocities. It is exact
for a body coasting without torque (momentum is kept inside the play), it
does not pump energy into the gear's contact spring (a symplectic step
keeps the oscillation's energy bounded where explicit Euler lets it grow),
and it costs one evaluation per step, which is what lets 1 ms of servo time
run in a few microseconds. The Karnopp stick rule needs the step's
zero-crossing test, which a one-evaluation step gives directly (an RK4
step would straddle the discontinuity four times). The **winding current**
is advanced with the exact exponential solution for the voltage and speed
held over the sub-step, ``i <- i_ss + (i - i_ss) exp(-h R / L)``, so a fast
electrical time constant (tens of microseconds) needs no tiny step.
:class:`~servoid.drivers.twin.params.TwinParams` refuses stiffness,
damping or inertia that would make the step inaccurate
(``omega h > 0.5``), naming the value.

The drive's firmware runs at the end of every sub-step that completes one
of its ticks (:mod:`servoid.drivers.twin.firmware`); its output (voltage)
is held until its next tick. With the output stage off the winding is open:
the current is cut within one sub-step (the freewheel decay through the
bridge's diodes lasts a few ``L/R``) and the motor coasts; the
regenerative braking of a motor spun above the supply voltage is not
modelled.
"""

from __future__ import annotations

import math

import numpy as np

from servoid.drivers.twin import _layout as L
from servoid.drivers.twin._jit import jit
from servoid.drivers.twin.firmware import control_tick, current_tick

__all__ = ["run", "run_sequence", "RECORD_FIELDS"]

#: Columns of the rows :func:`run_sequence` records at each host instant.
RECORD_FIELDS = (
    "motor_counts",
    "load_counts",
    "velocity",
    "current",
    "duty",
    "setpoint",
    "theta_m",
    "theta_l",
    "tick_k",
)


@jit
def _friction_step(
    w: float,
    stuck: bool,
    torque: float,
    inertia: float,
    viscous: float,
    coulomb: float,
    breakaway: float,
    stribeck: float,
    h: float,
) -> tuple[float, bool]:
    """One sub-step of a body's speed under ``torque`` (everything but friction) with a stick state."""
    if stuck:
        if abs(torque) <= breakaway:
            return 0.0, True
        # break-away: at zero speed the sliding friction is the break-away level (top of the Stribeck hump)
        sgn = 1.0 if torque > 0.0 else -1.0
        return h * (torque - sgn * breakaway) / inertia, False
    if w > 0.0:
        sgn = 1.0
    elif w < 0.0:
        sgn = -1.0
    elif torque > breakaway:
        sgn = 1.0
    elif torque < -breakaway:
        sgn = -1.0
    else:
        return 0.0, True
    level = coulomb
    if stribeck > 0.0:
        x = w / stribeck
        level += (breakaway - coulomb) * math.exp(-x * x)
    w_new = w + h * (torque - viscous * w - sgn * level) / inertia
    if w_new * sgn > 0.0:
        return w_new, False
    # the speed reached zero within this sub-step: the body sticks there, unless the torque
    # exceeds the break-away level, when it turns round for the rest of the sub-step
    if abs(torque) <= breakaway:
        return 0.0, True
    rest = 1.0 - w / (w - w_new)  # share of the sub-step left after the zero crossing
    sgn = 1.0 if torque > 0.0 else -1.0
    return rest * h * (torque - sgn * breakaway) / inertia, False


@jit
def _store(state: np.ndarray, th_m: float, w_m: float, th_l: float, w_l: float, cur: float, k: int) -> None:
    """Write the loop's local copies of the bodies, the current and the clock back to ``state``."""
    state[L.S_TH_M] = th_m
    state[L.S_W_M] = w_m
    state[L.S_TH_L] = th_l
    state[L.S_W_L] = w_l
    state[L.S_I] = cur
    state[L.S_K] = k


@jit
def run(
    phys: np.ndarray,
    fw: np.ndarray,
    state: np.ndarray,
    mem: np.ndarray,
    n_sub: int,
    noise_m: np.ndarray,
    noise_l: np.ndarray,
    noise_at: int,
) -> int:
    """Advance the twin ``n_sub`` sub-steps, running the firmware at its ticks.

    Parameters
    ----------
    phys, fw : numpy.ndarray
        Constants (:mod:`servoid.drivers.twin._layout`).
    state, mem : numpy.ndarray
        State and firmware memory, updated in place.
    n_sub : int
        Sub-steps to run.
    noise_m, noise_l : numpy.ndarray
        Standard normal draws, one per control tick, for the motor and load
        encoders (empty: no noise).
    noise_at : int
        Index of the next unused draw.

    Returns
    -------
    int
        The index of the next unused draw after this run.
    """
    h = phys[L.P_H]
    j_m = phys[L.P_J_M]
    b_m = phys[L.P_B_M]
    tc_m = phys[L.P_TC_M]
    ts_m = phys[L.P_TS_M]
    vs_m = phys[L.P_VS_M]
    kt = phys[L.P_KT]
    ke = phys[L.P_KE]
    res = phys[L.P_R]
    decay = phys[L.P_EL_DECAY]
    n = phys[L.P_N]
    half_play = phys[L.P_HALF_PLAY]
    k_g = phys[L.P_K]
    c_g = phys[L.P_C]
    eta = phys[L.P_ETA]
    j_l = phys[L.P_J_L]
    b_l = phys[L.P_B_L]
    tc_l = phys[L.P_TC_L]
    ts_l = phys[L.P_TS_L]
    vs_l = phys[L.P_VS_L]
    mgl = phys[L.P_MGL]
    spt = int(fw[L.F_SPT])
    spc = int(fw[L.F_SPC])
    n_noise_m = noise_m.shape[0]
    n_noise_l = noise_l.shape[0]

    th_m = state[L.S_TH_M]
    w_m = state[L.S_W_M]
    th_l = state[L.S_TH_L]
    w_l = state[L.S_W_L]
    cur = state[L.S_I]
    volt = state[L.S_V]
    stuck_m = state[L.S_STUCK_M] > 0.5
    stuck_l = state[L.S_STUCK_L] > 0.5
    enabled = state[L.S_ENABLED] > 0.5
    k = int(state[L.S_K])
    n_stuck_m = 0
    n_stuck_l = 0
    n_contact = 0
    torque_c = state[L.S_TORQUE_C]

    for _ in range(n_sub):
        # winding current: exact for the voltage and speed held over the sub-step
        if enabled:
            i_ss = (volt - ke * w_m) / res
            cur = i_ss + (cur - i_ss) * decay
        else:
            cur = 0.0
        # gear: free inside the play, a one-sided spring and damper past a flank
        delta = th_m / n - th_l
        torque_c = 0.0
        if delta > half_play:
            torque_c = k_g * (delta - half_play) + c_g * (w_m / n - w_l)
            if torque_c < 0.0:
                torque_c = 0.0
            n_contact += 1
        elif delta < -half_play:
            torque_c = k_g * (delta + half_play) + c_g * (w_m / n - w_l)
            if torque_c > 0.0:
                torque_c = 0.0
            n_contact += 1
        # who drives: the power the gear passes to the load; at rest, the motor if its own
        # torque pushes the way the contact does (a passive motor is always driven)
        power = torque_c * w_l
        if power > 0.0 or (power == 0.0 and torque_c * cur > 0.0):
            reaction = torque_c / (n * eta)  # the motor drives the load
        else:
            reaction = torque_c * eta / n  # the load drives the motor
        w_m, stuck_m = _friction_step(w_m, stuck_m, kt * cur - reaction, j_m, b_m, tc_m, ts_m, vs_m, h)
        w_l, stuck_l = _friction_step(w_l, stuck_l, torque_c - mgl * math.sin(th_l), j_l, b_l, tc_l, ts_l, vs_l, h)
        th_m += h * w_m
        th_l += h * w_l
        if enabled:
            if stuck_m:
                n_stuck_m += 1
            if stuck_l:
                n_stuck_l += 1
        k += 1
        tick = k % spt == 0
        if tick or k % spc == 0:
            _store(state, th_m, w_m, th_l, w_l, cur, k)  # the firmware samples the bodies
            if tick:
                nm = noise_m[noise_at] if noise_at < n_noise_m else 0.0
                nl = noise_l[noise_at] if noise_at < n_noise_l else 0.0
                noise_at += 1
                control_tick(phys, fw, state, mem, nm, nl)
            current_tick(phys, fw, state, mem)
            volt = state[L.S_V]
            enabled = state[L.S_ENABLED] > 0.5

    _store(state, th_m, w_m, th_l, w_l, cur, k)
    state[L.S_V] = volt
    state[L.S_STUCK_M] = 1.0 if stuck_m else 0.0
    state[L.S_STUCK_L] = 1.0 if stuck_l else 0.0
    state[L.S_TORQUE_C] = torque_c
    state[L.S_N_STUCK_M] += n_stuck_m
    state[L.S_N_STUCK_L] += n_stuck_l
    state[L.S_N_CONTACT] += n_contact
    return noise_at


@jit
def run_sequence(
    phys: np.ndarray,
    fw: np.ndarray,
    state: np.ndarray,
    mem: np.ndarray,
    u: np.ndarray,
    n_sub: np.ndarray,
    noise_m: np.ndarray,
    noise_l: np.ndarray,
    out: np.ndarray,
) -> None:
    """Host sampling in one call: at each host instant record the registers, send ``u[j]``, run ``n_sub[j]``.

    Parameters
    ----------
    phys, fw : numpy.ndarray
        Constants.
    state, mem : numpy.ndarray
        State and firmware memory, updated in place.
    u : numpy.ndarray
        Set points, output rad, one per host instant.
    n_sub : numpy.ndarray
        Sub-steps from each host instant to the next (int64).
    noise_m, noise_l : numpy.ndarray
        Encoder noise draws for all the control ticks of the run (or empty).
    out : numpy.ndarray
        ``(len(u), len(RECORD_FIELDS))`` array, filled with the readings taken
        at each instant, before its command.
    """
    at = 0
    for j in range(u.shape[0]):
        out[j, 0] = state[L.S_CNT_M]
        out[j, 1] = state[L.S_CNT_L]
        out[j, 2] = state[L.S_VEL]
        out[j, 3] = state[L.S_CUR]
        out[j, 4] = state[L.S_DUTY]
        out[j, 5] = state[L.S_SP]
        out[j, 6] = state[L.S_TH_M]
        out[j, 7] = state[L.S_TH_L]
        out[j, 8] = state[L.S_TICK_K]
        state[L.S_PENDING] = u[j]
        state[L.S_HAS_PENDING] = 1.0
        at = run(phys, fw, state, mem, n_sub[j], noise_m, noise_l, at)
