"""A multi-joint session: several servos of one bus (:class:`~servoid.drivers.bus.BusDriver`) measured together.

:func:`~servoid.session.run_session` given a bus runs :class:`BusSampler`: per
slot one command per joint, one group transaction, one :class:`JointsSample`.
The slot's status (``ok``, ``late``, ``missed``, ``timeout``) and its usable
verdict are the slot's, for every joint: the goals go out in one SYNC_WRITE
and the readings come back in one SYNC_READ, so a lost or late transaction
is lost or late for every joint -- and a guard window after it covers every
joint whose servo runs on its own clock. (A per-joint rule would only
matter for faults that hit one joint and not the others within one packet,
which the group transaction does not have: one silent servo fails the whole
group read.)

The recording has the slot's columns once and a group per joint
(:func:`joint_columns`): ``reference_<id>``, ``u_<id>``, ``y_<id>``,
``clamped_<id>``. :func:`joint_result` gives one joint's samples as a
one-servo :class:`~servoid.session.SessionResult` (what identification takes);
:class:`JointFeed` hands one joint's samples to a one-servo listener (an
online estimator per joint).

How the joints are excited (:func:`bus_excitation`): ``sequential`` -- one
joint after the other, the others holding their centre -- or ``together``,
each joint its own independent (differently seeded) signal. See
docs/feetech.md for the measurement and why ``sequential`` is the default.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from servoid.bus_facts import DEFAULT_MODE, MODES
from servoid.errors import ConfigError
from servoid.session.listeners import SampleListener
from servoid.session.sampler import BusSampler, SessionResult
from servoid.session.samples import JointsSample, joint_columns

__all__ = ["JointsSample", "BusSampler", "JointFeed", "joint_columns", "joint_result", "bus_excitation",
           "EXCITATION_MODES", "DEFAULT_EXCITATION_MODE"]  # fmt: skip

#: How the joints of a bus are excited (:func:`bus_excitation`), and the default (docs/feetech.md says why).
EXCITATION_MODES, DEFAULT_EXCITATION_MODE = MODES, DEFAULT_MODE


class JointFeed:
    """Hands one joint's samples to a one-servo listener (an :class:`~servoid.session.EstimatorFeed` per joint).

    Parameters
    ----------
    index : int
        The joint's position in the bus.
    listener : SampleListener
        The one-servo listener.
    """

    def __init__(self, index: int, listener: SampleListener) -> None:
        self.index = index
        self.listener = listener

    def on_sample(self, sample: JointsSample, usable: bool) -> None:
        self.listener.on_sample(sample.joint(self.index), usable)


def joint_result(result: SessionResult, index: int) -> SessionResult:
    """Joint ``index``'s samples of a multi-joint session as a one-servo result (same statuses and verdicts).

    Parameters
    ----------
    result : SessionResult
        A multi-joint session's result.
    index : int
        The joint's position in the bus.
    """
    samples = tuple(s.joint(index) for s in result.samples)  # type: ignore[attr-defined]
    return dataclasses.replace(result, samples=samples, _arrays={})


def bus_excitation(
    make: Callable[[int, int], np.ndarray], joints: int, samples: int, *, mode: str = DEFAULT_EXCITATION_MODE
) -> tuple[np.ndarray, list[slice]]:
    """The excitation of a bus, ``(slots, joints)``, and the slots that excite each joint.

    Parameters
    ----------
    make : callable
        ``make(seed_offset, n)``: one joint's signal of ``n`` samples (seeded
        by the caller's seed plus ``seed_offset``), user unit, around 0.
    joints : int
        Number of joints.
    samples : int
        Samples each joint is excited for.
    mode : {"sequential", "together"}
        ``sequential``: joint ``i`` is excited in slots ``i*samples ..
        (i+1)*samples``, every other joint holds 0 (the run is ``joints``
        times longer); ``together``: every joint for all ``samples`` slots,
        each its own signal.
    """
    if mode not in EXCITATION_MODES:
        raise ConfigError(f"mode (={mode!r}) must be one of {', '.join(EXCITATION_MODES)}")
    if mode == "together":
        u = np.column_stack([make(i, samples) for i in range(joints)])
        return u, [slice(0, samples)] * joints
    u = np.zeros((joints * samples, joints))
    blocks = []
    for i in range(joints):
        block = slice(i * samples, (i + 1) * samples)
        u[block, i] = make(i, samples)
        blocks.append(block)
    return u, blocks
