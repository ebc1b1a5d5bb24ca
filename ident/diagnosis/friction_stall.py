"""When to name ``friction_stall``: the rule of the research study (Q4), on numbers any fit of the servo-loop model gives.

Fit the chosen loop structure with and without its friction terms
(``fc``, ``fs``, ``vs``, ``veps``). The effect matters when the friction
terms improve the validation NRMSE by more than :data:`MIN_GAIN` **and** the
fitted stall ratio ``fs / (kv v_typ)`` is at least :data:`MIN_STALL_RATIO`:
the drive needs at least 5 % of a typical speed error to break away
(measured gains on records with a stalling motor: 3.8-80 %). The band a user
compares with the play is ``fs / (kv kp)`` (a P loop's static hysteresis);
a cascade with a velocity integrator stalls for ``fs / (ki |e|)`` instead.
"""

from __future__ import annotations

from servoid.ident.models.effect_names import FRICTION_STALL

__all__ = ["matters", "stall_band", "describe", "MIN_GAIN", "MIN_STALL_RATIO", "FRICTION_STALL"]

#: Relative validation gain the friction terms must buy.
MIN_GAIN = 0.02
#: ``fs / (kv v_typ)`` from which the stall matters.
MIN_STALL_RATIO = 0.05


def matters(nrmse_with: float, nrmse_without: float, stall_ratio: float) -> bool:
    """Whether ``friction_stall`` is named: the friction terms gain > 2 % in validation and the stall ratio >= 0.05.

    Parameters
    ----------
    nrmse_with, nrmse_without : float
        Validation NRMSE of the loop model with and without its friction terms.
    stall_ratio : float
        ``fs / (kv v_typ)``, ``v_typ = std(diff y) / T``.
    """
    if not nrmse_without > 0.0:
        return False
    gain = 1.0 - nrmse_with / nrmse_without
    return gain > MIN_GAIN and stall_ratio >= MIN_STALL_RATIO


def stall_band(fs: float, kv: float, kp: float) -> float:
    """The static stall band ``fs / (kv kp)`` of a P loop (unit of y), what the verdict compares with the play.

    Parameters
    ----------
    fs : float
        Break-away friction as an acceleration (unit of y per s^2).
    kv, kp : float
        The velocity and position loop gains (1/s); infinity when either is not positive.
    """
    return fs / (kv * kp) if kv > 0.0 and kp > 0.0 else float("inf")


def describe(band: float, play: float, unit: str = "") -> str:
    """One line for the report.

    Parameters
    ----------
    band, play : float
        The stall band and the play (unit of y).
    unit : str
        The unit's name, or "".
    """
    return (f"{FRICTION_STALL}: the drive stalls after reversals; its stall band {band:.3g}{unit and ' ' + unit} "
            f"against a play of {play:.3g}{unit and ' ' + unit}")  # fmt: skip
