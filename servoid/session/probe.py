"""Run the probe (:mod:`servoid.ident.online.probe`) through a driver: a short session, then what it found.

The probe's set points stay within ``limits.centre +/- amplitude``, and the
driver's own limits still clamp every command; the recording of the probe is
kept beside the main one when a path is given. Unlike an estimator, the probe
uses every measured output, late ones included.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from servoid.drivers.base import Driver
from servoid.ident.online.probe import ProbeResult, analyse_probe, probe_input
from servoid.session.sampler import SessionConfig, SessionResult, run_session

__all__ = ["run_probe"]


def run_probe(
    driver: Driver, amplitude: float, config: SessionConfig, *, recording: str | Path | None = None
) -> tuple[ProbeResult, SessionResult]:
    """Probe an open driver's servo.

    Parameters
    ----------
    driver : Driver
        An open driver.
    amplitude : float
        Largest excursion from the driver's centre, inside the user's limits.
    config : SessionConfig
        The session's period and policies (the probe runs at the rate of the identification after it).
    recording : path, optional
        Where to write the probe's samples as they arrive.

    Returns
    -------
    ProbeResult, SessionResult
        What the probe found, and its session.

    Raises
    ------
    DataError
        When the probe's record cannot tell (too many samples lost, no movement).
    """
    u, plan = probe_input(driver.limits.centre, amplitude, config.rate_hz)
    session = run_session(driver, u, config, recording=recording, metadata={"probe": "True"})
    # every measured output counts here, late ones and those in guard windows too: the probe reads
    # rises, levels and noise, which a sample measured a slot late barely moves, while the
    # estimator's rule (a Dynamixel's late slots open 10-sample windows) left 5 % of a loaded run
    measured = np.isfinite(session.y)
    found = analyse_probe(session.u, session.y, measured, plan)
    return dataclasses.replace(found, readings=driver.readings_side), session
