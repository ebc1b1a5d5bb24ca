"""The grey-box servo-loop model: position P over velocity P(I) over the motor, friction, and the play in one of two places.

The second model structure next to the paper's pseudo-Wiener model. One
simulator serves both places of the play (:mod:`~servoid.ident.models.structure_names`)::

    set point r --> [position P, kp] --> v_cmd (clipped at vmax) --> [velocity P(I), kv, ki] --> drive
                      ^ feedback: the motor side x   (output_backlash: the loop is closed on the motor)
                      |           or the load y      (play_in_loop: the encoder sits on the load, the horn)
    motor side:  dv/dt = kv (v_cmd - v) + z - F(v) + a0,   z' = ki (v_cmd - v),   x' = v
    friction:    F(v) = (fc + (fs - fc) exp(-(v/vs)^2)) tanh(v/veps)    (Coulomb + Stribeck, smoothed at v = 0)
    load:        massless -- the play operator of x: y = x - c1 pushed up, y = x + c2 pushed down, else held
                 or (opt-in, mu > 0) its own inertia mu and friction al, meeting the flanks in rigid
                 impacts of restitution e (:func:`_advance_load`)
                 or (opt-in, mu > 0 and wc > 0) the same load on a compliant contact: a spring of natural
                 frequency wc and damping ratio zeta outside the play (:func:`_advance_contact`)
                 either with (opt-in, als > al) a break-away: the load's friction als at rest, falling to al
                 over the speed vls (:func:`_load_level`)
    velocity filter (opt-in, tv > 0): the velocity loop feeds back vf, the motor side's speed through a first-order
                 filter, vf' = (v - vf) / tv, in place of v (kv (v_cmd - vf), z' = ki (v_cmd - vf)): a cascade
                 drive's velocity estimate, the encoder's differences filtered (:func:`_filtered`)
    torque lag (opt-in, tq > 0): the motor feels a, the velocity loop's command a_cmd = kv (v_cmd - vf) + z through
                 a first-order lag, a' = (a_cmd - a) / tq (dv/dt = a - F(v) + a0): a cascade drive's current loop
                 (:func:`_lagged`)
    reading:     y_hat(k) = y(t_k), read at the host instant before the command u(k) is applied

Why this form (physics, see the issue-12 study): a drive that closes its loop
on the motor side makes the motor a closed loop of the set point that the
output encoder reads through the play -- the pseudo-Wiener structure, whose
linear block is here the continuous cascade sampled by the host. A servo whose
encoder sits on the horn closes the loop on ``y``: the motor keeps moving
while the load waits in the play, so the play changes the loop's dynamics
instead of offsetting its output. A drive whose velocity integrator must wind
up past break-away friction stalls after each reversal: that stall is ``fs``
and ``ki`` here, not play. A P loop driving a DC motor through PWM (a
Dynamixel, a Feetech) is this structure with ``ki = 0``: back-EMF is the
velocity loop. ``a0`` is a constant force (a drive's offset, a spring, a
slope), as an acceleration.

Units are the record's: positions in the unit of ``y`` (which must also be
the unit of the set point ``u``: the loop compares them), time in seconds.
Every term depends on differences of positions, so the model does not depend
on where the record's zero is.

Integration (:func:`simulate_kernel`): a fixed sub-step ``h = T / m`` with
``m = ceil(T kv / 0.15)`` (2..48; :func:`substeps`), the velocity loop and
the friction implicit (two Newton steps on the smooth friction), ``x += h v``.
Every operation is Lipschitz in the state and the parameters, so a free-run
simulation is continuous in the parameters and can be fitted by least
squares (:mod:`servoid.ident.offline.loop_fit`); a rigid stick-slip model
cannot (its cost is piecewise constant at fine scales).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident._jit import jit, jit_inline
from servoid.ident.models.structure_names import FEEDBACK, PLAY_IN_LOOP, STRUCTURES

__all__ = [
    "PARAM_NAMES",
    "LOAD_NAMES",
    "CONTACT_NAMES",
    "BREAKAWAY_NAMES",
    "FILTER_NAMES",
    "LAG_NAMES",
    "KERNEL_NAMES",
    "STATE_SIZE",
    "ServoLoopModel",
    "simulate_kernel",
    "simulate_pair_kernel",
    "initial_state",
    "advance",
    "substeps",
    "H_KV_MAX",
]

#: The parameter vector's layout for :func:`simulate_kernel` (the one place it is written).
PARAM_NAMES: tuple[str, ...] = ("kp", "kv", "ki", "vmax", "fc", "fs", "vs", "veps", "a0", "c1", "c2", "s0")
#: The load's own parameters (:func:`_advance_load`), after :data:`PARAM_NAMES` in the kernel's vector: the
#: inertia ratio ``mu``, the restitution ``e`` of an impact on a flank and the load's friction ``al``.
#: A vector without them, and ``mu = 0``, is the massless load (the play operator), as are model files
#: written before they existed.
LOAD_NAMES: tuple[str, ...] = ("mu", "e", "al")
#: The gear contact's own parameters (:func:`_advance_contact`), after :data:`LOAD_NAMES`: the contact's
#: natural frequency ``wc`` on the load's inertia, rad/s, and its damping ratio ``zeta``. ``wc = 0`` (and a
#: vector without them) is the rigid flank of :func:`_advance_load`.
CONTACT_NAMES: tuple[str, ...] = ("wc", "zeta")
#: The load's break-away (:func:`_load_level`), after :data:`CONTACT_NAMES`: its static friction ``als`` as a
#: deceleration (``als > al``; 0, or a vector without them: none, the load's friction is ``al`` at every speed) and
#: the speed ``vls`` over which it falls to ``al`` (Stribeck's law, as the motor's ``fs``, ``vs``).
BREAKAWAY_NAMES: tuple[str, ...] = ("als", "vls")
#: The velocity loop's filter (:func:`_filtered`), after :data:`BREAKAWAY_NAMES`: the time constant ``tv`` of the
#: first-order filter on the speed the velocity loop feeds back, s (0, or a vector without it: none, the loop feeds
#: back the motor side's speed itself). Any model, massless or not.
FILTER_NAMES: tuple[str, ...] = ("tv",)
#: The drive's torque lag (:func:`_lagged`), after :data:`FILTER_NAMES`: the time constant ``tq`` of the first-order
#: lag between the velocity loop's command and the motor's torque, s (a cascade drive's current loop, about one over
#: its bandwidth; 0, or a vector without it: none, the torque is the command at once). Any model, massless or not.
LAG_NAMES: tuple[str, ...] = ("tq",)
#: The kernel's parameter vector: :data:`PARAM_NAMES`, :data:`LOAD_NAMES`, :data:`CONTACT_NAMES`,
#: :data:`BREAKAWAY_NAMES`, :data:`FILTER_NAMES`, then :data:`LAG_NAMES`.
KERNEL_NAMES: tuple[str, ...] = PARAM_NAMES + LOAD_NAMES + CONTACT_NAMES + BREAKAWAY_NAMES + FILTER_NAMES + LAG_NAMES
#: A rebound slower than this share of the speed the load's friction takes off in one sub-step ends in
#: contact (:func:`_advance_load`): small, so that a small restitution still bounces (the fit needs its slope).
REBOUND_SHARE = 0.01
#: Largest ``h wc sqrt(1 + mu)`` of a compliant contact's sub-step (:func:`_advance_contact`): about 60
#: sub-steps per period of the contact's ringing, so that the explicit contact force neither damps nor
#: excites it (the fit's own sub-step, :data:`H_KV_MAX`, is up to ten times longer than the contact's period).
H_WC_MAX = 0.1
#: Floats in the simulation's state: ``[x, y, v, z, w, contact, vf, a]`` (:func:`initial_state`).
STATE_SIZE = 8

#: Largest ``h kv`` of a sub-step: the implicit velocity step stays accurate (the study measured
#: 0.7 count rms of model error on the XM430 at ``h kv = 0.8``, 0.35 at 0.1).
H_KV_MAX = 0.15


def substeps(sample_period_s: float, kv: float, tq: float = 0.0) -> int:
    """Sub-steps per host period so that ``h kv <= H_KV_MAX`` (and ``h / tq <= H_KV_MAX`` with a torque lag), 2..48.

    Parameters
    ----------
    sample_period_s : float
        The host period ``T``, s.
    kv : float
        The velocity loop's rate, 1/s.
    tq : float, optional
        The drive's torque lag, s (0: none; :func:`_lagged`): its implicit step is as accurate as the velocity loop's.

    Returns
    -------
    int
        ``ceil(T rate / H_KV_MAX)`` clipped to 2..48, the rate ``kv`` or ``1 / tq`` if larger.
    """
    rate = max(kv, 1.0 / tq) if tq > 0.0 else kv
    return int(np.clip(np.ceil(sample_period_s * rate / H_KV_MAX), 2, 48))


@jit
def _friction(v: float, fc: float, fs: float, vs: float, veps: float) -> tuple[float, float]:
    """Coulomb + Stribeck friction smoothed at zero speed and its slope: ``F = (fc + (fs - fc) exp(-(v/vs)^2)) tanh(v/veps)``."""
    hump = 0.0
    dhump = 0.0
    if fs > fc:
        hump = (fs - fc) * math.exp(-(v / vs) * (v / vs))
        dhump = -2.0 * v / (vs * vs) * hump
    level = fc + hump
    t = math.tanh(v / veps)
    return level * t, dhump * t + level * (1.0 - t * t) / veps


@jit
def initial_state(p: np.ndarray, y0: float, state: np.ndarray) -> None:
    """The loop at rest with the load at ``y0``: fills ``state`` (:data:`STATE_SIZE` floats, see below).

    Parameters
    ----------
    p : ndarray
        The parameters in the order of :data:`PARAM_NAMES`.
    y0 : float
        The load's position.
    state : ndarray
        ``[x, y, v, z, w, contact, vf, a]``, overwritten: motor side, load, motor speed, integrator, load speed,
        the flank in contact (0 free, +1 the motor pushes up, -1 down; a massive load only), the filtered
        speed the velocity loop feeds back (with ``tv > 0``; else it follows the motor speed) and the drive's
        torque as an acceleration (with ``tq > 0``: the lagged command, :func:`_lagged`; else not used).
    """
    c1, c2, s0 = p[9], p[10], p[11]
    state[0] = y0 - c2 + s0 * (c1 + c2)
    state[1] = y0
    state[2] = 0.0
    # at rest with an integrator, it holds the constant force
    state[3] = -p[8] if p[2] > 0.0 else 0.0
    # a massive load starts at rest, free inside the play (a flank it rests on is met at zero speed: contact)
    state[4] = 0.0
    state[5] = 0.0
    state[6] = 0.0
    # at rest the velocity error is 0: the drive's torque is the integrator's
    state[7] = state[3]


@jit
def advance(p: np.ndarray, feedback_load: bool, state: np.ndarray, r: float, period: float, m: int) -> float:
    """Run the loop for one host period with the set point ``r``; returns the load's position at its end.

    Parameters
    ----------
    p : ndarray
        The parameters in the order of :data:`PARAM_NAMES`.
    feedback_load : bool
        True: the position loop reads the load (play in the loop); False: the motor side.
    state : ndarray
        :data:`STATE_SIZE` floats (:func:`initial_state`), advanced in place.
    r : float
        The set point, held for the period.
    period : float
        The host period, s.
    m : int
        Sub-steps per period.
    """
    kp, kv, ki, vmax = p[0], p[1], p[2], p[3]
    fc, fs, vs, veps = p[4], p[5], p[6], p[7]
    a0, c1, c2 = p[8], p[9], p[10]
    if veps <= 0.0:
        veps = 1e-300
    if p.shape[0] > 12 and p[12] > 0.0:
        if p.shape[0] > 15 and p[15] > 0.0:
            return _advance_contact(p, feedback_load, state, r, period, m, veps)
        return _advance_load(p, feedback_load, state, r, period, m, veps)
    h = period / m
    g, gq = _gains(p, h)
    x, yl, v, z, vf, a = state[0], state[1], state[2], state[3], state[6], state[7]
    for _ in range(m):
        vcmd, base = _command(x, yl, v, z, r, feedback_load, kp, kv, vmax, a0, h)
        base, kvf = _filtered(base, kv, vf, g, h)
        base, kvf, drive = _lagged(base, kvf, v, h * a0, a, gq, h)
        vn = v
        for _ in range(2):
            vn = _newton(vn, base, kvf, fc, fs, vs, veps, h)
        vf = _filter_moved(vf, vn, g)
        a = _torque_moved(a, drive, kvf, vn, gq, h)
        x, yl, z = _moved(x, yl, z, vcmd, vn, vf, ki, c1, c2, h)
        v = vn
    state[0], state[1], state[2], state[3], state[6], state[7] = x, yl, v, z, vf, a
    return float(yl)


#: Where the kernel's vector holds the velocity filter's ``tv`` and the torque lag's ``tq`` (:data:`KERNEL_NAMES`).
_TV_INDEX = KERNEL_NAMES.index("tv")
_TQ_INDEX = KERNEL_NAMES.index("tq")


@jit_inline
def _weight(p: np.ndarray, index: int, h: float) -> float:
    """A first-order lag's weight of its new input in one implicit sub-step ``h``: ``h / (tau + h)`` (1: none).

    ``tau`` is ``p[index]`` (0, or a vector too short to hold it: none).
    """
    if p.shape[0] > index and p[index] > 0.0:
        return h / (float(p[index]) + h)
    return 1.0


@jit
def _gains(p: np.ndarray, h: float) -> tuple[float, float]:
    """The velocity filter's weight of the new speed (``tv``, :func:`_filtered`) and the torque lag's of the new
    command (``tq``, :func:`_lagged`) in one implicit sub-step ``h`` (:func:`_weight`; 1: the term is off)."""
    return _weight(p, _TV_INDEX, h), _weight(p, _TQ_INDEX, h)


@jit_inline
def _filtered(base: float, kv: float, vf: float, g: float, h: float) -> tuple[float, float]:
    """The implicit velocity step's known part and rate when the loop feeds back the filtered speed (``g < 1``).

    The drive's velocity estimate, the encoder's differences through a first-order filter of time constant ``tv``
    (``vf' = (v - vf) / tv``), feeds its velocity loop: ``dv/dt = kv (v_cmd - vf) + z + a0 - F(v)``. Implicit in
    ``v`` and ``vf`` together, ``vf_new = vf + g (v_new - vf)`` with ``g = h / (tv + h)``, the step is
    :func:`_newton`'s with the rate ``kv g`` and ``h kv (1 - g) vf`` off its known part; ``g = 1`` (no filter)
    returns both unchanged.
    """
    if g < 1.0:
        return base - h * kv * (1.0 - g) * vf, kv * g
    return base, kv


@jit_inline
def _filter_moved(vf: float, vn: float, g: float) -> float:
    """The filtered speed after a sub-step whose motor speed is ``vn`` (:func:`_filtered`; ``g = 1``: ``vn`` itself)."""
    if g < 1.0:
        return vf + g * (vn - vf)
    return vn


@jit_inline
def _lagged(
    base: float, kvf: float, inert: float, ext: float, a: float, gq: float, h: float
) -> tuple[float, float, float]:
    """The implicit velocity step's known part and rate when the drive's torque lags its command (``gq < 1``).

    The velocity loop commands the torque ``a_cmd = kv (v_cmd - vf) + z`` (as an acceleration); a cascade drive's
    current loop makes it with a first-order lag, ``a' = (a_cmd - a) / tq``, and the motor feels ``a``:
    ``dv/dt = a + a0 - F(v)`` (and the load's push). Implicit in ``v`` and ``a`` together, ``a_new = a + gq (a_cmd_new
    - a)`` with ``gq = h / (tq + h)``: of the step's known part ``base`` (``inert``, the motor's momentum term, plus
    ``ext``, ``h`` times the forces the drive does not make, plus ``h`` times the command's known part) the command's
    part is weighted ``gq`` and ``h (1 - gq) a`` added, and the rate ``kvf`` on the new speed is weighted ``gq``.
    Returns the new ``base``, the rate and ``drive``, ``h`` times the new torque's known part (:func:`_torque_moved`);
    ``gq = 1`` (no lag) returns ``base`` and ``kvf`` unchanged.
    """
    if gq < 1.0:
        drive = gq * (base - inert - ext) + (1.0 - gq) * h * a
        return inert + ext + drive, kvf * gq, drive
    return base, kvf, 0.0


@jit_inline
def _torque_moved(a: float, drive: float, kq: float, vn: float, gq: float, h: float) -> float:
    """The drive's torque after a sub-step whose motor speed is ``vn`` (:func:`_lagged`'s ``drive`` and rate ``kq``;
    ``gq = 1``: ``a`` unchanged, not used)."""
    if gq < 1.0:
        return drive / h - kq * vn
    return a


@jit_inline
def _command(
    x: float,
    yl: float,
    v: float,
    z: float,
    r: float,
    feedback_load: bool,
    kp: float,
    kv: float,
    vmax: float,
    a0: float,
    h: float,
) -> tuple[float, float]:
    """A sub-step's velocity command and the known part of its implicit velocity step (:func:`advance`)."""
    vcmd = _velocity_command(kp, r - (yl if feedback_load else x), vmax)
    # implicit step of dv/dt = kv (vcmd - v) + z + a0 - F(v): two Newton steps on the friction (_newton)
    return vcmd, v + h * (kv * vcmd + z + a0)  # fmt: skip


@jit_inline
def _newton(vn: float, base: float, kv: float, fc: float, fs: float, vs: float, veps: float, h: float) -> float:
    """One Newton step of the implicit velocity step from ``vn`` (:func:`_command`'s ``base``)."""
    f, df = _friction(vn, fc, fs, vs, veps)
    return vn - (vn * (1.0 + h * kv) - base + h * f) / (1.0 + h * kv + h * df)


@jit_inline
def _moved(
    x: float, yl: float, z: float, vcmd: float, vn: float, vf: float, ki: float, c1: float, c2: float, h: float
) -> tuple[float, float, float]:
    """The sub-step's end from the new speed ``vn``: the integrator (of ``vcmd - vf``, the speed fed back,
    :func:`_filter_moved`), the motor side and the massless load."""
    if ki > 0.0:
        z += h * ki * (vcmd - vf)
    x += h * vn
    # the massless load: the play operator of the motor side
    if x - yl > c1:
        yl = x - c1
    elif yl - x > c2:
        yl = x + c2
    return x, yl, z


@jit
def _motor_step(
    v: float, vcmd: float, z: float, a0: float, kv: float, fc: float, fs: float, vs: float, veps: float, h: float,
    vf: float = 0.0, g: float = 1.0, a: float = 0.0, gq: float = 1.0,
) -> tuple[float, float]:  # fmt: skip
    """The motor side's implicit velocity step alone and the drive's torque after it (the massless load's,
    :func:`advance`; ``vf``, ``g``: the velocity filter's, :func:`_filtered`; ``a``, ``gq``: the torque lag's,
    :func:`_lagged`)."""
    base, kv = _filtered(v + h * (kv * vcmd + z + a0), kv, vf, g, h)
    base, kv, drive = _lagged(base, kv, v, h * a0, a, gq, h)
    vn = v
    for _ in range(2):
        f, df = _friction(vn, fc, fs, vs, veps)
        vn -= (vn * (1.0 + h * kv) - base + h * f) / (1.0 + h * kv + h * df)
    return vn, _torque_moved(a, drive, kv, vn, gq, h)


@jit_inline
def _velocity_command(kp: float, error: float, vmax: float) -> float:
    """The position loop's velocity command ``kp error``, clipped at ``vmax`` (0: no limit)."""
    vcmd = kp * error
    if vmax > 0.0:
        if vcmd > vmax:
            return vmax
        if vcmd < -vmax:
            return -vmax
    return vcmd


@jit
def _load_step(w: float, al: float, veps: float, h: float) -> float:
    """The load coasting for ``h``: the implicit step of ``dw/dt = -al sat(w / veps)``, in closed form.

    Coulomb friction smoothed by a linear ramp over ``|w| < veps`` (as the motor's is by a tanh):
    implicit, so that a large ``al`` (the massless limit) stops the load within a step without
    ringing; the two branches meet at ``|w| = veps + h al``, so the step is continuous in ``w``.
    """
    if abs(w) - h * al >= veps:
        return w - h * al if w > 0.0 else w + h * al
    return w / (1.0 + h * al / veps)


@jit
def _sat(v: float, veps: float) -> tuple[float, float]:
    """``sat(v / veps)`` (the load's friction shape) and its slope in ``v``."""
    if v >= veps:
        return 1.0, 0.0
    if v <= -veps:
        return -1.0, 0.0
    return v / veps, 1.0 / veps


@jit
def _load_level(w: float, al: float, als: float, vls: float) -> tuple[float, float]:
    """The load's friction level at speed ``w`` and its slope: ``al + (als - al) exp(-(w / vls)^2)`` (``als <= al``: ``al``).

    The load's break-away (Stribeck's law, as the motor's :func:`_friction`): a load at rest takes ``als`` to move,
    one sliding faster than ``vls`` ``al``. It multiplies the shape ``sat(w / veps)`` (:func:`_sat`).
    """
    if als <= al:
        return al, 0.0
    hump = (als - al) * math.exp(-(w / vls) * (w / vls))
    return al + hump, -2.0 * w / (vls * vls) * hump


@jit
def _breakaway(p: np.ndarray) -> tuple[float, float]:
    """``(als, vls)`` of ``p`` (:data:`BREAKAWAY_NAMES`; ``(0, 1)``, no break-away, for a shorter vector)."""
    if p.shape[0] > 18 and p[17] > p[14] and p[18] > 0.0:
        return p[17], p[18]
    return 0.0, 1.0


@jit
def _advance_load(
    p: np.ndarray, feedback_load: bool, state: np.ndarray, r: float, period: float, m: int, veps: float
) -> float:
    """:func:`advance` with a load of its own inertia that meets the flanks in rigid impacts (``mu > 0``).

    Two bodies at the output, in accelerations per the motor side's inertia: the motor side
    ``x`` (the loop's dynamics) and the load ``y`` (inertia ``mu`` times the motor's, friction
    ``al sat(w / veps)`` as its own deceleration)::

        free flight (x - c1 < y < x + c2):  each body its own dynamics;   dw/dt = -al sat(w / veps)
        contact (a flank):                  one body, (1 + mu) dv/dt = kv (v_cmd - v) + z + a0 - F(v) - mu al sat(v / veps)
        impact on a flank (Newton's law):   v+ + mu w+ = v + mu w,   v+ - w+ = -e (v - w)

    The gear contact is stiff (the twins' ring at 785-909 rad/s, a period far below the loop's),
    so at the loop's time scale a flank is rigid and its damping is a coefficient of restitution
    ``e`` (``exp(-zeta pi / sqrt(1 - zeta^2))`` of a contact of damping ratio ``zeta``). The impact
    is found within the sub-step by the gap's linear crossing; the rest of the sub-step runs with
    the velocities after it. A rebound slower than a share (:data:`REBOUND_SHARE`) of the speed the
    load's friction takes off in one sub-step (``h al``) ends in contact, so the bounces cannot
    chatter without end. Contact ends
    when it would have to pull: when the load's own friction alone would slow it less than the
    motor side slows (the load coasts ahead, e.g. after a reversal of the motor). With ``e = 0``
    and ``al`` large the load stops wherever the motor leaves it: the play operator of the
    massless load, the limit ``mu -> 0``.
    """
    kp, kv, ki, vmax = p[0], p[1], p[2], p[3]
    fc, fs, vs = p[4], p[5], p[6]
    a0, c1, c2 = p[8], p[9], p[10]
    mu, e, al = p[12], p[13], p[14]
    als, vls = _breakaway(p)
    h = period / m
    g, gq = _gains(p, h)
    x, yl, v, z, w, side, vf, a = state[0], state[1], state[2], state[3], state[4], state[5], state[6], state[7]
    for _ in range(m):
        x, yl, v, z, w, side, vf, a = _load_substep(
            x, yl, v, z, w, side, r, feedback_load, kp, kv, ki, vmax, fc, fs, vs, veps, a0, c1, c2, mu, e, al, h,
            als, vls, vf, g, a, gq,
        )  # fmt: skip
    state[0], state[1], state[2], state[3], state[4], state[5], state[6], state[7] = x, yl, v, z, w, side, vf, a
    return float(yl)


@jit_inline
def _load_substep(
    x: float,
    yl: float,
    v: float,
    z: float,
    w: float,
    side: float,
    r: float,
    feedback_load: bool,
    kp: float,
    kv: float,
    ki: float,
    vmax: float,
    fc: float,
    fs: float,
    vs: float,
    veps: float,
    a0: float,
    c1: float,
    c2: float,
    mu: float,
    e: float,
    al: float,
    h: float,
    als: float = 0.0,
    vls: float = 1.0,
    vf: float = 0.0,
    g: float = 1.0,
    a: float = 0.0,
    gq: float = 1.0,
) -> tuple[float, float, float, float, float, float, float, float]:
    """One sub-step ``h`` of :func:`_advance_load`: the new ``(x, y, v, z, w, contact, vf, a)`` (``als``, ``vls``: the
    load's break-away, :func:`_load_level`; ``vf``, ``g``: the velocity filter's, :func:`_filtered`; ``a``, ``gq``: the
    torque lag's, :func:`_lagged`)."""
    vcmd = _velocity_command(kp, r - (yl if feedback_load else x), vmax)
    if side != 0.0:
        # one body: the implicit step of the pair, two Newton steps on both frictions
        base, kvf = _filtered((1.0 + mu) * v + h * (kv * vcmd + z + a0), kv, vf, g, h)
        base, kvf, drive = _lagged(base, kvf, (1.0 + mu) * v, h * a0, a, gq, h)
        vc = v
        for _ in range(2):
            f, df = _friction(vc, fc, fs, vs, veps)
            sl, dsl = _sat(vc, veps)
            lv, dlv = _load_level(vc, al, als, vls)
            gap = vc * (1.0 + mu + h * kvf) + h * f + h * mu * lv * sl - base
            vc -= gap / (1.0 + mu + h * kvf + h * df + h * mu * lv * dsl + h * mu * dlv * sl)
        sl, _ = _sat(vc, veps)
        lv, _ = _load_level(vc, al, als, vls)
        # the flank's force on the load, mu (dv/dt + al sat): it pushes, it never pulls
        if side * ((vc - v) / h + lv * sl) >= 0.0:
            vf = _filter_moved(vf, vc, g)
            a = _torque_moved(a, drive, kvf, vc, gq, h)
            if ki > 0.0:
                z += h * ki * (vcmd - vf)
            x += h * vc
            return x, x - c1 if side > 0.0 else x + c2, vc, z, vc, side, vf, a
        side = 0.0
    vn, a = _motor_step(v, vcmd, z, a0, kv, fc, fs, vs, veps, h, vf, g, a, gq)
    vf = _filter_moved(vf, vn, g)
    if ki > 0.0:
        z += h * ki * (vcmd - vf)
    wn = _load_step(w, _load_level(w, al, als, vls)[0], veps, h)
    d0 = x - yl
    xn = x + h * vn
    yn = yl + h * wn
    d1 = xn - yn
    hit = 0.0
    tau = 0.0
    if d1 > c1:
        hit = 1.0
        tau = (c1 - d0) / (d1 - d0) if d1 > d0 else 0.0
    elif d1 < -c2:
        hit = -1.0
        tau = (-c2 - d0) / (d1 - d0) if d1 < d0 else 0.0
    if hit != 0.0:
        tau = min(max(tau, 0.0), 1.0)
        # Newton's impact law with the momentum of the pair kept
        common = (vn + mu * wn) / (1.0 + mu)
        rebound = e * (vn - wn)
        if abs(rebound) <= REBOUND_SHARE * h * al:
            vn = common
            wn = common
            side = hit
        else:
            vn = common - mu * rebound / (1.0 + mu)
            wn = common + rebound / (1.0 + mu)
        xi = x + tau * (xn - x)
        xn = xi + (1.0 - tau) * h * vn
        yn = (xi - c1 if hit > 0.0 else xi + c2) + (1.0 - tau) * h * wn
        if side != 0.0:
            yn = xn - c1 if side > 0.0 else xn + c2
    return xn, yn, vn, z, wn, side, vf, a  # fmt: skip


@jit
def contact_substeps(sample_period_s: float, m: int, mu: float, wc: float) -> int:
    """Sub-steps per host period of a compliant contact: at least ``m``, and ``h wc sqrt(1 + mu) <= H_WC_MAX``.

    Parameters
    ----------
    sample_period_s : float
        The host period ``T``, s.
    m : int
        The loop's own sub-steps (:func:`substeps`).
    mu : float
        The load's inertia ratio.
    wc : float
        The contact's natural frequency on the load's inertia, rad/s.

    Returns
    -------
    int
    """
    return max(m, int(math.ceil(sample_period_s * wc * math.sqrt(1.0 + mu) / H_WC_MAX)))


@jit
def _advance_contact(
    p: np.ndarray, feedback_load: bool, state: np.ndarray, r: float, period: float, m: int, veps: float
) -> float:
    """:func:`advance` with a load of its own inertia on a compliant, damped gear contact (``mu > 0``, ``wc > 0``).

    The load of :func:`_advance_load` (inertia ``mu`` times the motor side's, friction ``al sat(w /
    veps)``), but a flank is a spring-damper, not a rigid wall: outside the play, by the penetration
    ``p = (x - y) - c1`` (up) or ``(x - y) + c2`` (down), the contact pushes the load with the
    acceleration ``f = wc^2 p + 2 zeta wc (v - w)`` (on the load's inertia) and never pulls
    (``f`` clipped at 0 on its side), and the motor side with ``-mu f``::

        dv/dt = kv (v_cmd - v) + z + a0 - F(v) - mu f,     dw/dt = f - al sat(w / veps)

    A real gear's mesh is a stiff spring: the contact lasts about ``pi / wc`` (4 ms at 785 rad/s),
    which against a host period of a few ms a rigid impact does not have. The contact is integrated
    with its own sub-step (:func:`contact_substeps`, ``h wc sqrt(1 + mu) <= 0.1``): the forces at
    the step's start, the motor's velocity loop and friction implicit as in :func:`advance`, the
    load's friction implicit (:func:`_load_step`), then the positions with the new speeds
    (semi-implicit Euler). ``e`` and the contact state ``state[5]`` are not used (``state[5]`` stays 0).
    """
    kp, kv, ki, vmax = p[0], p[1], p[2], p[3]
    fc, fs, vs = p[4], p[5], p[6]
    a0, c1, c2 = p[8], p[9], p[10]
    mu, al, wc, zeta = p[12], p[14], p[15], p[16]
    mc = contact_substeps(period, m, mu, wc)
    h = period / mc
    k2 = wc * wc
    c = 2.0 * zeta * wc
    g, gq = _gains(p, h)
    x, yl, v, z, w, vf, a = state[0], state[1], state[2], state[3], state[4], state[6], state[7]
    loop = (kp, kv, ki, vmax, fc, fs, vs, veps, a0, c1, c2)
    contact = (mu, al, k2, c) + _breakaway(p)
    for _ in range(mc):
        x, yl, v, z, w, vf, a = _contact_substep(x, yl, v, z, w, vf, r, feedback_load, loop, contact, h, g, a, gq)
    state[0], state[1], state[2], state[3], state[4], state[6], state[7] = x, yl, v, z, w, vf, a
    return float(yl)


@jit_inline
def _contact_force(x: float, yl: float, v: float, w: float, c1: float, c2: float, k2: float, c: float) -> float:
    """The compliant contact's push on the load at a sub-step's start (:func:`_advance_contact`; 0 inside the play)."""
    d = x - yl
    f = 0.0
    if d > c1:
        f = max(k2 * (d - c1) + c * (v - w), 0.0)
    elif d < -c2:
        f = min(k2 * (d + c2) + c * (v - w), 0.0)
    return f


@jit_inline
def _contact_moved(
    x: float,
    yl: float,
    z: float,
    w: float,
    f: float,
    vcmd: float,
    vn: float,
    vf: float,
    ki: float,
    al: float,
    veps: float,
    h: float,
    als: float = 0.0,
    vls: float = 1.0,
) -> tuple[float, float, float, float]:
    """A compliant sub-step's end from the motor's new speed ``vn``: the integrator (of ``vcmd - vf``, the speed fed
    back, :func:`_filter_moved`), the load's speed, the positions (the load's friction at its level at the step's
    start, :func:`_load_level`)."""
    if ki > 0.0:
        z += h * ki * (vcmd - vf)
    w = _load_step(w + h * f, _load_level(w, al, als, vls)[0], veps, h)
    x += h * vn
    yl += h * w
    return x, yl, z, w


@jit_inline
def _contact_substep(
    x: float,
    yl: float,
    v: float,
    z: float,
    w: float,
    vf: float,
    r: float,
    feedback_load: bool,
    loop: tuple[float, float, float, float, float, float, float, float, float, float, float],
    contact: tuple[float, float, float, float, float, float],
    h: float,
    g: float,
    a: float = 0.0,
    gq: float = 1.0,
) -> tuple[float, float, float, float, float, float, float]:
    """One sub-step of :func:`_advance_contact`: ``(x, yl, v, z, w, vf, a)`` after it.

    ``loop`` is :func:`_loop_params`'s ``(kp, kv, ki, vmax, fc, fs, vs, veps, a0, c1, c2)``, ``contact`` is
    ``(mu, al, wc^2, 2 zeta wc, als, vls)``, ``g`` the velocity filter's weight (:func:`_gains`), ``a`` the
    drive's torque and ``gq`` the torque lag's weight (:func:`_gains`).
    """
    kp, kv, ki, vmax, fc, fs, vs, veps, a0, c1, c2 = loop
    mu, al, k2, c, als, vls = contact
    f = _contact_force(x, yl, v, w, c1, c2, k2, c)
    vcmd, base = _command(x, yl, v, z, r, feedback_load, kp, kv, vmax, a0 - mu * f, h)
    base, kvf = _filtered(base, kv, vf, g, h)
    base, kvf, drive = _lagged(base, kvf, v, h * (a0 - mu * f), a, gq, h)
    vn = v
    for _ in range(2):
        vn = _newton(vn, base, kvf, fc, fs, vs, veps, h)
    vf = _filter_moved(vf, vn, g)
    a = _torque_moved(a, drive, kvf, vn, gq, h)
    x, yl, z, w = _contact_moved(x, yl, z, w, f, vcmd, vn, vf, ki, al, veps, h, als, vls)
    return x, yl, vn, z, w, vf, a


@jit
def simulate_kernel(
    p: np.ndarray, feedback_load: bool, u: np.ndarray, y0: float, period: float, m: int, y_out: np.ndarray
) -> None:
    """Free-run simulation of the servo loop from rest; fills ``y_out`` (the load at the host instants).

    Parameters
    ----------
    p : ndarray
        The parameters in the order of :data:`PARAM_NAMES`.
    feedback_load : bool
        True: the position loop reads the load (play in the loop); False: the motor side.
    u : ndarray
        Set points, each applied from its host instant (after that instant's reading) to the next.
    y0 : float
        The load at the first instant (the loop at rest there).
    period : float
        The host period, s.
    m : int
        Sub-steps per period.
    y_out : ndarray
        Output; ``y_out.shape[0] <= u.shape[0]`` samples are simulated (a fit stops at its last scored sample).
    """
    state = np.empty(STATE_SIZE)
    initial_state(p, y0, state)
    for k in range(y_out.shape[0]):
        y_out[k] = state[1]
        advance(p, feedback_load, state, u[k], period, m)


@jit_inline
def _at_rest(p: np.ndarray, y0: float) -> tuple[float, float, float, float, float, float, float, float]:
    """:func:`initial_state` as a tuple ``(x, y, v, z, w, contact, vf, a)``."""
    state = np.empty(STATE_SIZE)
    initial_state(p, y0, state)
    return state[0], state[1], state[2], state[3], state[4], state[5], state[6], state[7]


@jit_inline
def _loop_params(p: np.ndarray) -> tuple[float, float, float, float, float, float, float, float, float, float, float]:
    """``kp, kv, ki, vmax, fc, fs, vs, veps, a0, c1, c2`` of ``p``, ``veps`` as :func:`advance` reads it."""
    veps = p[7]
    if veps <= 0.0:
        veps = 1e-300
    return p[0], p[1], p[2], p[3], p[4], p[5], p[6], veps, p[8], p[9], p[10]


@jit
def simulate_pair_kernel(
    p: np.ndarray,
    q: np.ndarray,
    feedback_load: bool,
    u: np.ndarray,
    y0: float,
    period: float,
    m: int,
    y_p: np.ndarray,
    y_q: np.ndarray,
) -> None:
    """:func:`simulate_kernel` of two parameter vectors at once, into ``y_p`` and ``y_q`` (of one length).

    The two simulations run in one loop, sub-step by sub-step: each is a chain of dependent
    operations (two Newton steps per sub-step, each an ``exp`` and a ``tanh``), whose latency a
    core hides by working on the other chain meanwhile (the servo-loop fit's Jacobian columns: a
    pair in 0.57 of the time of the two one after the other, CiA 402 twin's 20 000-sample fit).
    Each output is :func:`simulate_kernel`'s to the bit: the same operations, in the same order.
    Two massive loads (``mu > 0``, :func:`_advance_load`) run side by side too (a pair in 0.8 of the time: its
    impacts branch), and two loads on compliant contacts (:func:`_advance_contact`: a pair in about 0.6 of
    the time); a massive load beside a massless one, and a compliant contact beside a rigid flank or a
    massless load, run the two one after the other.
    """
    massive_p, massive_q = p.shape[0] > 12 and p[12] > 0.0, q.shape[0] > 12 and q[12] > 0.0
    compliant_p = massive_p and p.shape[0] > 15 and p[15] > 0.0
    compliant_q = massive_q and q.shape[0] > 15 and q[15] > 0.0
    if compliant_p and compliant_q:
        # two compliant contacts, each on its own sub-step (:func:`contact_substeps`): while both have sub-steps left
        # in a host period their forces, commands and Newton steps alternate, then the one with more finishes alone
        x1, yl1, v1, z1, w1, _, vf1, a1 = _at_rest(p, y0)
        x2, yl2, v2, z2, w2, _, vf2, a2 = _at_rest(q, y0)
        loop1, loop2 = _loop_params(p), _loop_params(q)
        kp1, kv1, ki1, vmax1, fc1, fs1, vs1, veps1, a01, c11, c21 = loop1
        kp2, kv2, ki2, vmax2, fc2, fs2, vs2, veps2, a02, c12, c22 = loop2
        mu1, al1, wc1, zeta1 = p[12], p[14], p[15], p[16]
        mu2, al2, wc2, zeta2 = q[12], q[14], q[15], q[16]
        mc1, mc2 = contact_substeps(period, m, mu1, wc1), contact_substeps(period, m, mu2, wc2)
        h1, h2 = period / mc1, period / mc2
        (g1, gq1), (g2, gq2) = _gains(p, h1), _gains(q, h2)
        k21, k22 = wc1 * wc1, wc2 * wc2
        cd1, cd2 = 2.0 * zeta1 * wc1, 2.0 * zeta2 * wc2
        both = min(mc1, mc2)
        (als1, vls1), (als2, vls2) = _breakaway(p), _breakaway(q)
        contact1, contact2 = (mu1, al1, k21, cd1, als1, vls1), (mu2, al2, k22, cd2, als2, vls2)
        for k in range(y_p.shape[0]):
            y_p[k] = yl1
            y_q[k] = yl2
            r = u[k]
            for _ in range(both):
                f1 = _contact_force(x1, yl1, v1, w1, c11, c21, k21, cd1)
                f2 = _contact_force(x2, yl2, v2, w2, c12, c22, k22, cd2)
                vcmd1, base1 = _command(x1, yl1, v1, z1, r, feedback_load, kp1, kv1, vmax1, a01 - mu1 * f1, h1)
                vcmd2, base2 = _command(x2, yl2, v2, z2, r, feedback_load, kp2, kv2, vmax2, a02 - mu2 * f2, h2)
                base1, kvf1 = _filtered(base1, kv1, vf1, g1, h1)
                base2, kvf2 = _filtered(base2, kv2, vf2, g2, h2)
                base1, kvf1, drive1 = _lagged(base1, kvf1, v1, h1 * (a01 - mu1 * f1), a1, gq1, h1)
                base2, kvf2, drive2 = _lagged(base2, kvf2, v2, h2 * (a02 - mu2 * f2), a2, gq2, h2)
                vn1, vn2 = v1, v2
                for _ in range(2):
                    vn1 = _newton(vn1, base1, kvf1, fc1, fs1, vs1, veps1, h1)
                    vn2 = _newton(vn2, base2, kvf2, fc2, fs2, vs2, veps2, h2)
                vf1, vf2 = _filter_moved(vf1, vn1, g1), _filter_moved(vf2, vn2, g2)
                a1, a2 = _torque_moved(a1, drive1, kvf1, vn1, gq1, h1), _torque_moved(a2, drive2, kvf2, vn2, gq2, h2)
                x1, yl1, z1, w1 = _contact_moved(x1, yl1, z1, w1, f1, vcmd1, vn1, vf1, ki1, al1, veps1, h1, als1, vls1)
                x2, yl2, z2, w2 = _contact_moved(x2, yl2, z2, w2, f2, vcmd2, vn2, vf2, ki2, al2, veps2, h2, als2, vls2)
                v1, v2 = vn1, vn2
            for _ in range(mc1 - both):
                x1, yl1, v1, z1, w1, vf1, a1 = _contact_substep(
                    x1, yl1, v1, z1, w1, vf1, r, feedback_load, loop1, contact1, h1, g1, a1, gq1
                )
            for _ in range(mc2 - both):
                x2, yl2, v2, z2, w2, vf2, a2 = _contact_substep(
                    x2, yl2, v2, z2, w2, vf2, r, feedback_load, loop2, contact2, h2, g2, a2, gq2
                )
        return
    if massive_p != massive_q or compliant_p or compliant_q:
        simulate_kernel(p, feedback_load, u, y0, period, m, y_p)
        simulate_kernel(q, feedback_load, u, y0, period, m, y_q)
        return
    x1, yl1, v1, z1, w1, side1, vf1, a1 = _at_rest(p, y0)
    x2, yl2, v2, z2, w2, side2, vf2, a2 = _at_rest(q, y0)
    # the parameters in locals: the outputs are written in the loop, and the compiler cannot tell they do not alias p, q
    kp1, kv1, ki1, vmax1, fc1, fs1, vs1, veps1, a01, c11, c21 = _loop_params(p)
    kp2, kv2, ki2, vmax2, fc2, fs2, vs2, veps2, a02, c12, c22 = _loop_params(q)
    mu1, e1, al1, mu2, e2, al2 = (p[12], p[13], p[14], q[12], q[13], q[14]) if massive_p else (0.0,) * 6
    (als1, vls1), (als2, vls2) = _breakaway(p), _breakaway(q)
    h = period / m
    (g1, gq1), (g2, gq2) = _gains(p, h), _gains(q, h)
    for k in range(y_p.shape[0]):
        y_p[k] = yl1
        y_q[k] = yl2
        r = u[k]
        for _ in range(m):
            if massive_p:
                # two massive loads: :func:`_advance_load`'s sub-steps side by side
                x1, yl1, v1, z1, w1, side1, vf1, a1 = _load_substep(
                    x1, yl1, v1, z1, w1, side1, r, feedback_load, kp1, kv1, ki1, vmax1, fc1, fs1, vs1, veps1, a01, c11,
                    c21, mu1, e1, al1, h, als1, vls1, vf1, g1, a1, gq1,
                )  # fmt: skip
                x2, yl2, v2, z2, w2, side2, vf2, a2 = _load_substep(
                    x2, yl2, v2, z2, w2, side2, r, feedback_load, kp2, kv2, ki2, vmax2, fc2, fs2, vs2, veps2, a02, c12,
                    c22, mu2, e2, al2, h, als2, vls2, vf2, g2, a2, gq2,
                )  # fmt: skip
                continue
            # the two chains step by step side by side (their Newton steps too: that is what overlaps)
            vcmd1, base1 = _command(x1, yl1, v1, z1, r, feedback_load, kp1, kv1, vmax1, a01, h)
            vcmd2, base2 = _command(x2, yl2, v2, z2, r, feedback_load, kp2, kv2, vmax2, a02, h)
            base1, kvf1 = _filtered(base1, kv1, vf1, g1, h)
            base2, kvf2 = _filtered(base2, kv2, vf2, g2, h)
            base1, kvf1, drive1 = _lagged(base1, kvf1, v1, h * a01, a1, gq1, h)
            base2, kvf2, drive2 = _lagged(base2, kvf2, v2, h * a02, a2, gq2, h)
            vn1, vn2 = v1, v2
            for _ in range(2):
                vn1 = _newton(vn1, base1, kvf1, fc1, fs1, vs1, veps1, h)
                vn2 = _newton(vn2, base2, kvf2, fc2, fs2, vs2, veps2, h)
            vf1, vf2 = _filter_moved(vf1, vn1, g1), _filter_moved(vf2, vn2, g2)
            a1, a2 = _torque_moved(a1, drive1, kvf1, vn1, gq1, h), _torque_moved(a2, drive2, kvf2, vn2, gq2, h)
            x1, yl1, z1 = _moved(x1, yl1, z1, vcmd1, vn1, vf1, ki1, c11, c21, h)
            x2, yl2, z2 = _moved(x2, yl2, z2, vcmd2, vn2, vf2, ki2, c12, c22, h)
            v1, v2 = vn1, vn2


@dataclass(frozen=True)
class ServoLoopModel:
    """A servo-loop model in the units of its record (see the module docstring).

    Attributes
    ----------
    structure : str
        Where the play sits: a name of :data:`~servoid.ident.models.structure_names.STRUCTURES`
        (``output_backlash``: the loop reads the motor side; ``play_in_loop``: it reads the load).
    sample_period_s : float
        The host period ``T`` of the record, s.
    kp : float
        Position gain: velocity command per position error, 1/s.
    kv : float
        Velocity loop rate: acceleration per velocity error, 1/s.
    ki : float
        Velocity integrator, 1/s^2 (0: a P velocity loop).
    vmax : float
        Velocity command limit, unit/s (0: none).
    fc, fs : float
        Coulomb and break-away friction as accelerations, unit/s^2 (``fs >= fc``).
    vs, veps : float
        Stribeck speed and the smoothing speed at zero, unit/s.
    a0 : float
        Constant force as an acceleration, unit/s^2.
    c1, c2 : float
        The play's two sides (the load lags by ``c1`` going up, by ``c2`` going down), unit.
    s0 : float
        Where in the play the motor side starts: 0 on the down flank, 1 on the up flank.
    mu : float
        The load's inertia over the motor side's, both at the output (0: the massless load, the
        play operator; > 0: the load of :func:`_advance_load`).
    e : float
        The coefficient of restitution of an impact on a flank, 0..1 (with ``mu > 0``).
    al : float
        The load's own friction as a deceleration, unit/s^2 (with ``mu > 0``).
    wc : float
        The gear contact's natural frequency on the load's inertia, rad/s (with ``mu > 0``; 0: a rigid
        flank, the impacts of :func:`_advance_load`; > 0: the compliant contact of :func:`_advance_contact`).
    zeta : float
        The compliant contact's damping ratio (with ``wc > 0``).
    als : float
        The load's break-away friction as a deceleration, unit/s^2 (with ``mu > 0``; at or below ``al``: none).
    vls : float
        The speed over which the load's friction falls from ``als`` to ``al``, unit/s (with ``als > al``).
    tv : float
        The time constant of the first-order filter on the speed the velocity loop feeds back, s (0: none; a
        cascade drive's velocity estimate, :func:`_filtered`).
    tq : float
        The time constant of the first-order lag between the velocity loop's command and the motor's torque, s (0:
        none; a cascade drive's current loop, :func:`_lagged`).
    """

    structure: str
    sample_period_s: float
    kp: float
    kv: float
    ki: float = 0.0
    vmax: float = 0.0
    fc: float = 0.0
    fs: float = 0.0
    vs: float = 1.0
    veps: float = 1e-3
    a0: float = 0.0
    c1: float = 0.0
    c2: float = 0.0
    s0: float = 0.5
    mu: float = 0.0
    e: float = 0.0
    al: float = 0.0
    wc: float = 0.0
    zeta: float = 0.0
    als: float = 0.0
    vls: float = 0.0
    tv: float = 0.0
    tq: float = 0.0

    def __post_init__(self) -> None:
        if self.structure not in STRUCTURES:
            raise ConfigError(f"structure {self.structure!r} is not one of {', '.join(STRUCTURES)}")
        validation.positive("sample_period_s", self.sample_period_s)
        for name in ("kp", "kv", "vs", "veps"):
            validation.positive(name, getattr(self, name))
        for name in ("ki", "vmax", "fc", "fs", "c1", "c2", "mu", "al", "wc", "zeta", "als", "vls", "tv", "tq"):
            validation.non_negative(name, getattr(self, name))
        validation.in_unit_interval("e", self.e, open_low=False, open_high=False)
        validation.real("a0", self.a0)
        validation.in_unit_interval("s0", self.s0, open_low=False, open_high=False)

    @property
    def play(self) -> float:
        """The play ``c1 + c2``, in the unit of ``y``."""
        return self.c1 + self.c2

    @property
    def feedback_load(self) -> bool:
        """Whether the position loop reads the load (the play inside the loop)."""
        return FEEDBACK[self.structure] == FEEDBACK[PLAY_IN_LOOP]

    @property
    def substeps(self) -> int:
        """Sub-steps per host period of the simulation (:func:`substeps`)."""
        return substeps(self.sample_period_s, self.kv, self.tq)

    @property
    def massive(self) -> bool:
        """Whether the load has its own inertia (``mu > 0``: impacts on the flanks) rather than none."""
        return self.mu > 0.0

    @property
    def compliant(self) -> bool:
        """Whether a massive load meets the flanks on a compliant contact (``wc > 0``) rather than in rigid impacts."""
        return self.massive and self.wc > 0.0

    @property
    def breaks_away(self) -> bool:
        """Whether a massive load's friction has a break-away (``als > al``, ``vls > 0``: :func:`_load_level`)."""
        return self.massive and self.als > self.al and self.vls > 0.0

    @property
    def filtered(self) -> bool:
        """Whether the velocity loop feeds back a filtered speed (``tv > 0``: :func:`_filtered`)."""
        return self.tv > 0.0

    @property
    def lagged(self) -> bool:
        """Whether the drive's torque lags the velocity loop's command (``tq > 0``: :func:`_lagged`)."""
        return self.tq > 0.0

    def names(self) -> tuple[str, ...]:
        """The model's parameter names: :data:`PARAM_NAMES`, :data:`LOAD_NAMES` for a massive load,
        :data:`CONTACT_NAMES` for a compliant contact (or one that breaks away), :data:`BREAKAWAY_NAMES` for a
        load that breaks away, :data:`FILTER_NAMES` for a filtered velocity loop and :data:`LAG_NAMES` for a lagged torque."""
        if not self.massive:
            names = PARAM_NAMES
        elif self.breaks_away:
            names = PARAM_NAMES + LOAD_NAMES + CONTACT_NAMES + BREAKAWAY_NAMES
        else:
            names = PARAM_NAMES + LOAD_NAMES + CONTACT_NAMES if self.compliant else PARAM_NAMES + LOAD_NAMES
        names = names + FILTER_NAMES if self.filtered else names
        return names + LAG_NAMES if self.lagged else names

    def vector(self) -> np.ndarray:
        """The parameters in the order of :data:`KERNEL_NAMES` (what :func:`simulate_kernel` takes)."""
        return np.array([float(getattr(self, name)) for name in KERNEL_NAMES])

    @classmethod
    def from_vector(cls, structure: str, sample_period_s: float, p: np.ndarray) -> ServoLoopModel:
        """The model of a parameter vector in the order of :data:`KERNEL_NAMES` (or a leading part of it: :data:`PARAM_NAMES`
        alone, with :data:`LOAD_NAMES`, with :data:`CONTACT_NAMES`, with :data:`BREAKAWAY_NAMES`, with :data:`FILTER_NAMES`).

        Parameters
        ----------
        structure : str
            A name of :data:`~servoid.ident.models.structure_names.STRUCTURES`.
        sample_period_s : float
            The host period, s.
        p : ndarray
            The parameters.

        Returns
        -------
        ServoLoopModel
        """
        p = np.asarray(p, dtype=np.float64)
        parts = (PARAM_NAMES, LOAD_NAMES, CONTACT_NAMES, BREAKAWAY_NAMES, FILTER_NAMES, LAG_NAMES)
        names = KERNEL_NAMES[: p.size] if p.size in np.cumsum([len(part) for part in parts]) else PARAM_NAMES
        values = {name: float(v) for name, v in zip(names, p, strict=True)}
        return cls(structure=structure, sample_period_s=float(sample_period_s), **values)

    def params(self) -> dict[str, float]:
        """The parameters by name (:meth:`names`: the load's only for a massive load), in the record's units."""
        return {name: float(getattr(self, name)) for name in self.names()}

    def to_dict(self) -> dict[str, Any]:
        """Every field, JSON-ready (the model file's ``servo_loop`` object)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ServoLoopModel:
        """The model written by :meth:`to_dict`.

        Parameters
        ----------
        data : dict
            The fields by name; unknown keys are an error.

        Returns
        -------
        ServoLoopModel
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"unknown servo-loop field(s): {', '.join(unknown)}")
        try:
            return cls(**data)
        except TypeError as exc:
            raise ConfigError(f"servo-loop model: {exc}") from None

    def simulate(self, u: Any, *, y0: float | None = None) -> np.ndarray:
        """Free-run simulation: the load's position at each host instant.

        Parameters
        ----------
        u : array_like
            Set points, one per host period, in the unit of ``y``.
        y0 : float, optional
            The load at the first instant, where the loop rests (default ``u[0]``).

        Returns
        -------
        ndarray
            ``y_hat``, as long as ``u``.
        """
        u_arr = np.ascontiguousarray(validation.signal("u", u), dtype=np.float64)
        start = validation.real("y0", float(u_arr[0]) if y0 is None else y0)
        # the model depends on differences only: simulate around the first reading (keeps rounding small)
        out = np.empty_like(u_arr)
        simulate_kernel(self.vector(), self.feedback_load, u_arr - start, 0.0, self.sample_period_s, self.substeps, out)
        return out + start
