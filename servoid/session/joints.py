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
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid.bus_facts import DEFAULT_MODE, MODES
from servoid.drivers.base import Measurement
from servoid.drivers.clock import NS_PER_S
from servoid.errors import ConfigError
from servoid.session.listeners import SampleListener
from servoid.session.sampler import SessionResult, _Sampler
from servoid.session.samples import MISSED, TIMEOUT, Sample

__all__ = ["JointsSample", "BusSampler", "JointFeed", "joint_columns", "joint_result", "bus_excitation",
           "EXCITATION_MODES", "DEFAULT_EXCITATION_MODE"]  # fmt: skip

#: How the joints of a bus are excited (:func:`bus_excitation`), and the default (docs/feetech.md says why).
EXCITATION_MODES, DEFAULT_EXCITATION_MODE = MODES, DEFAULT_MODE


def joint_columns(ids: Sequence[int]) -> tuple[str, ...]:
    """A multi-joint recording's columns: the slot's, then ``reference_<id>, u_<id>, y_<id>, clamped_<id>`` per joint.

    Parameters
    ----------
    ids : sequence of int
        The servo IDs, in the order of the joints.
    """
    per_joint = tuple(f"{name}_{i}" for i in ids for name in ("reference", "u", "y", "clamped"))
    return ("k", "t", "t_actual", "status", "device_time", "exchange_s", *per_joint)


@dataclass(frozen=True, slots=True)
class JointsSample:
    """One slot of a multi-joint session: the slot's times and status, one value per joint for the rest.

    Attributes
    ----------
    k : int
        Slot index.
    t_scheduled, t_actual : float
        Scheduled and actual start of the group exchange, s from slot 0.
    reference, u, y : tuple of float
        Per joint: the excitation, the command the servo had, the measured position (NaN: none).
    status : str
        The slot's status, for every joint.
    device_time : float
        The first joint's device clock (NaN when it has none).
    exchange_s : float
        Duration of the group exchange, s.
    clamped : tuple of bool
        Per joint: whether its limits changed the command.
    """

    k: int
    t_scheduled: float
    t_actual: float
    reference: tuple[float, ...]
    u: tuple[float, ...]
    y: tuple[float, ...]
    status: str
    device_time: float = math.nan
    exchange_s: float = math.nan
    clamped: tuple[bool, ...] = ()

    def row(self) -> tuple[Any, ...]:
        """The recording row, in the order of :func:`joint_columns`."""
        clamped = self.clamped or (False,) * len(self.u)
        per_joint = [v for j in zip(self.reference, self.u, self.y, clamped) for v in (*j[:3], int(j[3]))]
        return (self.k, self.t_scheduled, self.t_actual, self.status, self.device_time, self.exchange_s, *per_joint)

    def joint(self, index: int) -> Sample:
        """Joint ``index``'s view of the slot, as a one-servo :class:`~servoid.session.Sample`.

        Parameters
        ----------
        index : int
            The joint's position in the bus (0 for the first ID).
        """
        clamped = bool(self.clamped[index]) if self.clamped else False
        return Sample(self.k, self.t_scheduled, self.t_actual, self.reference[index], self.u[index], self.y[index],
                      self.status, self.device_time, self.exchange_s, clamped)  # fmt: skip


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

    def on_sample(self, sample: JointsSample, usable: bool) -> None:  # type: ignore[override]
        self.listener.on_sample(sample.joint(self.index), usable)


class BusSampler(_Sampler):
    """The sampling loop over a :class:`~servoid.drivers.bus.BusDriver`: one :class:`JointsSample` per slot."""

    def _reference(self, k: int, value: Any) -> Any:
        reference = np.asarray(value, dtype=np.float64)
        joints = len(self.driver.joints)  # type: ignore[attr-defined]
        if reference.shape != (joints,):
            raise ConfigError(f"excitation[{k}] has shape {reference.shape}; the bus has {joints} joints")
        if not np.all(np.isfinite(reference)):
            raise ConfigError(f"excitation[{k}] (={reference.tolist()}) is not finite")
        return tuple(float(v) for v in reference)

    def _missed(self, k: int, scheduled: int, reference: Any) -> None:
        u = tuple(0.0 if held is None else held for held in self.driver.last_command)  # type: ignore[union-attr]
        nan = (math.nan,) * len(u)
        self._add(JointsSample(k, self._s(scheduled), math.nan, reference, u, nan, MISSED))  # type: ignore[arg-type]

    def _timeout(self, k: int, scheduled: int, start: int, end: int, reference: Any, command: Any) -> None:
        u = tuple(self.driver.last_command)  # type: ignore[arg-type]
        clamped = tuple(a != b for a, b in zip(u, command))
        self._add(JointsSample(k, self._s(scheduled), self._s(start), reference, u, (math.nan,) * len(u),  # type: ignore[arg-type]
                               TIMEOUT, exchange_s=(end - start) / NS_PER_S, clamped=clamped))  # fmt: skip

    def _measured(self, k: int, scheduled: int, start: int, end: int, reference: Any, m: Any) -> None:
        ms: tuple[Measurement, ...] = m
        status, device_time = self._status_of(k, scheduled, start, end, ms[0].device_time)
        self._add(JointsSample(k, self._s(scheduled), self._s(start), reference,  # type: ignore[arg-type]
                               tuple(x.command for x in ms), tuple(x.position for x in ms), status, device_time,
                               (end - start) / NS_PER_S, tuple(x.clamped for x in ms)))  # fmt: skip


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
