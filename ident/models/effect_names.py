"""The candidate effects by name, with a line each: the one place their names are defined.

Plain Python, so that ``servoid diagnose --help`` lists them without loading
NumPy; what each effect does to the model is in
:mod:`servoid.ident.models.effects`, which builds one ``Effect`` per name here.
"""

from __future__ import annotations

__all__ = [
    "NONE",
    "COULOMB_FRICTION",
    "INPUT_SATURATION",
    "DEAD_ZONE",
    "EXTRA_DELAY",
    "EXTRA_POLE",
    "SUMMARIES",
    "CANDIDATE_NAMES",
    "EFFECT_NAMES",
    "FRICTION_STALL",
    "FLANK_REBOUND",
    "LOOP_EFFECTS",
]

#: The name the diagnosis gives when nothing significant is missing.
NONE = "none"
COULOMB_FRICTION = "coulomb_friction"
INPUT_SATURATION = "input_saturation"
DEAD_ZONE = "dead_zone"
EXTRA_DELAY = "extra_delay"
EXTRA_POLE = "extra_pole"

#: One line per effect for reports and ``--help``, in the order candidates are tried and reported.
SUMMARIES: dict[str, str] = {
    COULOMB_FRICTION: "a force opposing the direction of motion, F_c sign(x(k-1) - x(k-2)), subtracted from the input",
    INPUT_SATURATION: "the drive's limit: the linear block sees clip(u, -L, L)",
    DEAD_ZONE: "an input dead band: |u| <= delta does nothing, beyond it u - delta sign(u)",
    EXTRA_DELAY: "the true delay is d + m samples",
    EXTRA_POLE: "one more real pole p with unit static gain: A(q)(1 - p/q), (1 - p) B(q)",
}

#: Every candidate, in the order they are tried.
CANDIDATE_NAMES: tuple[str, ...] = tuple(SUMMARIES)

#: Friction that stalls the drive: the motor holds after a reversal until the drive's integrator
#: (or, in a P loop, the position error) overcomes break-away friction. It lives inside the
#: servo-loop model (:mod:`servoid.ident.models.servo_loop`), not as an extension of the
#: pseudo-Wiener model, so it is not a candidate of the effect search above; the diagnosis names
#: it from the loop model's fit with and without its friction terms
#: (:func:`servoid.ident.diagnosis.friction_stall.matters`).
FRICTION_STALL = "friction_stall"

#: The load leaves the flank after the impact that ends each crossing of the play (a light horn on a lightly
#: damped gear contact bounces off it): the massless play operator cannot follow it and the play comes out
#: biased. Named from the massless servo-loop model's residual around the load's departures from a flank
#: (:func:`servoid.ident.diagnosis.flank_rebound.rebound`), not a candidate of the effect search above.
FLANK_REBOUND = "flank_rebound"

#: Effects of the servo-loop model, named by the diagnosis when they matter.
LOOP_EFFECTS: dict[str, str] = {
    FRICTION_STALL: "the drive stalls after each reversal until its integrator overcomes break-away friction "
    "(inside the servo loop; a black box books it as play)",
    FLANK_REBOUND: "the load rebounds off the flank the motor hits after each reversal (a light horn on a lightly "
    "damped gear; the massless play is biased small)",
}

#: Every name the diagnosis can give: the candidates, the servo loop's effects and ``"none"``.
EFFECT_NAMES: tuple[str, ...] = (*CANDIDATE_NAMES, *LOOP_EFFECTS, NONE)
