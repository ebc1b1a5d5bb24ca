"""Several servos on one bus in one session: one group write and one group read per sample.

``dxl:///dev/ttyUSB0?id=1,2,3`` or ``feetech:///dev/ttyACM0?id=1,2,3,4,5,6``
opens a :class:`BusDriver`: one vendor driver per ID (its own limits, units,
held commands, counters, torque-off), the first of which opens the port; the
others use it. Per sample, :meth:`BusDriver.exchange` takes one command per
joint, lets every joint's driver apply its limits and rounding
(:meth:`~servoid.drivers.base.Driver.begin_exchange`), sends every goal in
one SYNC_WRITE and reads every joint's block back in one SYNC_READ (the
SDKs' GroupSyncWrite / GroupSyncRead), and lets each joint's driver confirm
its goal and guard its position (:meth:`~servoid.drivers.base.Driver.end_exchange`).

One transaction, one outcome: a joint that does not answer fails the group
read (the SDK reads the answers in order and stops at the first missing
one), a corrupted SYNC_WRITE is lost for every joint, so a sample is usable
for every joint or for none -- the sampling session decides once per sample
(:class:`~servoid.session.UsableRule`), as for one servo.

The cost per sample: one packet out with ``n`` goals, one packet out with
the ID list, ``n`` status packets back, each after its servo's Return Delay
Time. ``benchmarks/bus.py`` measures the rate it allows.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Sequence
from typing import Any

from servoid.drivers.base import Driver, DriverStats, Measurement
from servoid.errors import ConfigError, ServoidError

__all__ = ["BusDriver", "bus_ids"]

log = logging.getLogger("servoid.drivers")


def bus_ids(text: str) -> list[int]:
    """The IDs of a URL's ``id`` option: ``"1"`` or ``"1,2,3"``.

    Parameters
    ----------
    text : str
        The option's text.
    """
    try:
        ids = [int(part) for part in str(text).replace(" ", "").split(",")]
    except ValueError:
        raise ConfigError(f"id (={text!r}) must be a servo ID or IDs separated by commas, e.g. 1,2,3") from None
    if len(set(ids)) != len(ids):
        raise ConfigError(f"id (={text!r}) names a servo twice")
    return ids


class BusDriver:
    """Several servos of one bus behind one driver (see the module docstring).

    Parameters
    ----------
    joints : sequence of Driver
        One vendor driver per servo, not yet open, of a class that offers
        ``share_port`` and ``group_exchange``
        (:class:`~servoid.drivers._sdk_port.SdkTransactions`); the first opens the port.
    url : str
        The URL that named them.
    """

    def __init__(self, joints: Sequence[Driver], *, url: str = "") -> None:
        if len(joints) < 2:
            raise ConfigError(f"joints (={len(joints)}) must be two or more drivers: one servo needs no bus driver")
        owner = joints[0]
        for joint in joints[1:]:
            joint.share_port(owner)  # type: ignore[attr-defined]
        self.joints = tuple(joints)
        self.url = url
        self._is_open = False

    # ---- what the session asks of a driver ----------------------------------------------------
    @property
    def scheme(self) -> str:
        return self.joints[0].scheme

    @property
    def carries_slots(self) -> bool:
        return self.joints[0].carries_slots

    @property
    def clock_resolution_s(self) -> float:
        return self.joints[0].clock_resolution_s

    @property
    def position_unit(self) -> Any:
        return self.joints[0].position_unit

    @property
    def command_unit(self) -> Any:
        return self.joints[0].command_unit

    @property
    def ids(self) -> tuple[int, ...]:
        """The servo IDs, in the order of the joints."""
        return tuple(int(j.servo_id) for j in self.joints)  # type: ignore[attr-defined]

    @property
    def is_open(self) -> bool:
        return self._is_open

    @property
    def torque_enabled(self) -> bool:
        return any(j.torque_enabled for j in self.joints)

    @property
    def last_command(self) -> tuple[float | None, ...]:
        """Each joint's last command sent (user unit)."""
        return tuple(j.last_command for j in self.joints)

    @property
    def stats(self) -> DriverStats:
        """The joints' counters summed (a group failure counts once, on the first joint)."""
        total = DriverStats()
        for j in self.joints:
            for name, value in vars(j.stats).items():
                setattr(total, name, getattr(total, name) + value)
        return total

    @property
    def identity(self) -> dict[str, Any]:
        """Each joint's identity, by ID."""
        return {"driver": self.scheme, "joints": [j.identity for j in self.joints]}

    def describe(self) -> str:
        return self.url or f"{type(self.joints[0]).__name__} x {len(self.joints)}"

    def open(self) -> BusDriver:
        """Open the port (the first joint) and every servo on it; torque stays off."""
        if self._is_open:
            return self
        opened: list[Driver] = []
        try:
            for j in self.joints:
                j.open()
                opened.append(j)
        except BaseException:
            for j in reversed(opened):
                j.close()
            raise
        self._is_open = True
        return self

    def enable(self) -> None:
        """Switch every joint's torque on (all off again if one refuses)."""
        try:
            for j in self.joints:
                j.enable()
        except BaseException:
            self.disable()
            raise

    def disable(self) -> None:
        """Switch every joint's torque off; each is tried, the first failure raised after."""
        failure: BaseException | None = None
        for j in self.joints:
            try:
                if j.is_open:
                    j.disable()
            except ServoidError as exc:
                failure = failure or exc
        if failure is not None:
            raise failure

    def set_sample_period(self, period_s: float) -> None:
        """Tell every joint the period of the exchanges to come, s."""
        for j in self.joints:
            j.set_sample_period(period_s)

    def close(self) -> None:
        """Torque off and close every joint, the port's owner last; safe to call twice."""
        for j in reversed(self.joints):
            with contextlib.suppress(Exception):
                j.close()  # logs, never raises
        self._is_open = False

    def __enter__(self) -> BusDriver:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- per sample ----------------------------------------------------------------------------
    def exchange(self, u: Sequence[float], *, slot: int | None = None) -> tuple[Measurement, ...]:
        """Command every joint (``u``, one per joint, user unit) and read every joint, in one group transaction.

        Parameters
        ----------
        u : sequence of float
            One command per joint, in the order of :attr:`joints`.
        slot : int, optional
            The session's slot number.

        Raises
        ------
        ConfigError
            ``u`` has the wrong length, or a value is not finite.
        DriverTimeout, DriverError
            As for one servo; the sample is lost for every joint.
        """
        if len(u) != len(self.joints):
            raise ConfigError(f"u has {len(u)} commands; the bus has {len(self.joints)} joints (ids {self.ids})")
        owner = self.joints[0]
        pending = [j.begin_exchange(value, slot=slot) for j, value in zip(self.joints, u)]
        natives = [int(round(j.command_unit.to_native(p.command))) for j, p in zip(self.joints, pending)]
        readings = owner.call(owner.group_exchange, self.joints, natives)  # type: ignore[attr-defined]
        return tuple(j.end_exchange(p, r) for j, p, r in zip(self.joints, pending, readings))
