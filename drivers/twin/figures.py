"""Measure a twin the way a datasheet's figures are measured, to hold it against the vendor's numbers.

* **No-load speed**: a light output (a tenth of the preset's load, no
  friction, the horn alone), the firmware's own loop at its limit (a set
  point far away), the mean speed once it has settled.
* **Stall torque**: the output held (a load whose break-away is far above
  any torque the servo makes), the duty at its limit; the torque the gear
  passes once everything is still. The motor runs into the held output and
  comes to rest against its friction, so the figure lies within the
  friction band (a percent or two of the stall torque) around the ideal
  value -- as on a rig that loads a servo until it stops.
* **Resolution**: counts per output revolution of the output encoder.

The published figures themselves live with the presets
(:data:`servoid.drivers.twin.presets.PUBLISHED`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from servoid.drivers.twin.params import TwinParams
from servoid.drivers.twin.servo import Twin

__all__ = ["Figures", "measure", "no_load_speed", "stall_torque"]


@dataclass(frozen=True)
class Figures:
    """A twin's datasheet figures, as measured on the twin.

    Attributes
    ----------
    no_load_speed_rpm : float
        Output speed with nothing on the output, rpm.
    stall_torque_nm : float
        Output torque with the output held, N m.
    stall_current_a : float
        Winding current meanwhile, A.
    output_cpr : float
        Counts of the output encoder per output revolution.
    """

    no_load_speed_rpm: float
    stall_torque_nm: float
    stall_current_a: float
    output_cpr: float


def _far(params: TwinParams) -> float:
    """A set point far enough to keep the loop at its limit, inside the travel."""
    return min(3.0, 0.45 * params.range_rad) if math.isfinite(params.range_rad) else 3.0


def no_load_speed(params: TwinParams, *, settle_s: float = 0.25, window_s: float = 0.2) -> float:
    """The output speed with a bare horn, rad/s.

    Parameters
    ----------
    params : TwinParams
        The servo; its load is replaced by a tenth of it, without friction.
    settle_s, window_s : float
        Time to reach speed, and the window the speed is averaged over, s.
    """
    # a tenth of the inertia, and the gear's damping scaled to keep its damping ratio
    horn = params.replace(
        load_inertia_kgm2=0.1 * params.load_inertia_kgm2,
        load_coulomb_nm=0.0,
        load_breakaway_nm=0.0,
        load_viscous_nms=0.0,
        load_mass_kg=0.0,
        gear_damping_nms=params.gear_damping_nms / math.sqrt(10.0),
    )
    twin = Twin(horn)
    twin.enable()
    twin.command(_far(params))
    twin.advance(settle_s)
    start, t0 = twin.physics().load_rad, twin.time_s
    twin.advance(window_s)
    return (twin.physics().load_rad - start) / (twin.time_s - t0)


def stall_torque(params: TwinParams, *, hold_s: float = 0.5) -> tuple[float, float]:
    """The torque at the held output and the current meanwhile, (N m, A).

    Parameters
    ----------
    params : TwinParams
        The servo; its load is replaced by one that cannot move.
    hold_s : float
        Time from the command to the reading, s.
    """
    held = params.replace(load_coulomb_nm=1e4, load_breakaway_nm=1e4, load_mass_kg=0.0)
    twin = Twin(held)
    twin.enable()
    twin.command(0.5)
    twin.advance(hold_s)
    ph = twin.physics()
    return ph.contact_torque_nm, ph.current_a


def measure(params: TwinParams) -> Figures:
    """All the figures of one servo.

    Parameters
    ----------
    params : TwinParams
        The servo.
    """
    torque, current = stall_torque(params)
    return Figures(
        no_load_speed_rpm=no_load_speed(params) * 60.0 / (2.0 * math.pi),
        stall_torque_nm=torque,
        stall_current_a=current,
        output_cpr=params.output_counts_per_rev,
    )
