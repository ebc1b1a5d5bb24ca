"""Open a driver from a URL: one registry, vendor libraries imported only on use.

URL forms::

    sim://xm430?snr=40                              the simulated servo (a twin; sim://model the model itself)
    serial:///dev/ttyUSB0?baud=1000000              the serial bench controller
    can://virtual/ch0?protocol=cia402&node=1        a CAN drive (python-can interface / channel)
    dxl:///dev/ttyUSB0?id=1&baud=1000000            a ROBOTIS Dynamixel
    feetech:///dev/ttyUSB0?id=1&baud=1000000        a Feetech STS servo
    feetech:///dev/ttyUSB0?id=1,2,3&min=-1,-0.5,-1  three servos on one bus, a limit per joint

Every driver also accepts the safety limits ``min``, ``max``,
``max_step``, ``amplitude``, ``centre`` and ``guard`` (user unit). On a bus
(``id=1,2,3``) each limit takes one value for every joint or one value per
joint, comma-separated in the order of the IDs. Unknown schemes and unknown
options are rejected by name, with the valid ones listed.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING
from urllib.parse import parse_qsl, urlsplit

from servoid.errors import ConfigError, MissingDependency

if TYPE_CHECKING:  # pragma: no cover
    from servoid.drivers.base import Driver, DriverURL

__all__ = ["register", "schemes", "parse_url", "driver_class", "driver_from_url", "extra_for"]

#: scheme -> "module:Class", imported when a URL with that scheme is opened.
_REGISTRY: dict[str, str] = {
    "sim": "servoid.drivers.sim:SimDriver",
    "serial": "servoid.drivers.serial:SerialDriver",
    "can": "servoid.drivers.can:CanDriver",
    "dxl": "servoid.drivers.dynamixel:DynamixelDriver",
    "feetech": "servoid.drivers.feetech:FeetechDriver",
}

#: Third-party module -> (the PyPI package that provides it, the servoid extra that installs it), for messages.
_PACKAGES = {"serial": ("pyserial", "serial"), "can": ("python-can", "can"), "canopen": ("canopen", "can"),
             "msgpack": ("msgpack", "can"), "dynamixel_sdk": ("dynamixel-sdk", "dxl"),
             "scservo_sdk": ("feetech-servo-sdk", "feetech")}  # fmt: skip


def register(scheme: str, target: str) -> None:
    """Map ``scheme`` to a driver class given as ``"package.module:Class"``.

    Parameters
    ----------
    scheme : str
        The URL scheme, a bare name such as ``"sim"``.
    target : str
        ``"package.module:Class"``, imported when a URL with ``scheme`` is opened.
    """
    if "://" in scheme or not scheme.isidentifier():
        raise ConfigError(f"scheme (={scheme!r}) must be a bare name such as 'sim'")
    if ":" not in target:
        raise ConfigError(f"target (={target!r}) must look like 'package.module:Class'")
    _REGISTRY[scheme] = target


def schemes() -> tuple[str, ...]:
    """The registered URL schemes."""
    return tuple(sorted(_REGISTRY))


def parse_url(url: str) -> DriverURL:
    """Split a driver URL into scheme, host, path and options.

    Parameters
    ----------
    url : str
        ``scheme://host/path?key=value&...``.

    Raises
    ------
    ConfigError
        No scheme, an unknown scheme, or an option given twice.
    """
    from servoid.drivers.base import DriverURL

    if not isinstance(url, str) or "://" not in url:
        raise ConfigError(f"driver URL (={url!r}) must look like scheme://...; schemes: {', '.join(schemes())}")
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme not in _REGISTRY:
        raise ConfigError(f"unknown driver scheme {scheme!r} in {url!r}; known: {', '.join(schemes())}")
    options: dict[str, str] = {}
    for key, value in parse_qsl(parts.query, keep_blank_values=True):
        if key in options:
            raise ConfigError(f"{url}: option {key!r} is given twice")
        options[key] = value
    return DriverURL(raw=url, scheme=scheme, host=parts.netloc, path=parts.path, options=options)


def driver_class(scheme: str) -> type[Driver]:
    """The driver class for ``scheme``, imported now.

    Raises
    ------
    ConfigError
        Unknown scheme.
    MissingDependency
        The driver's vendor library is not installed (the message names the package).
    """
    try:
        target = _REGISTRY[scheme]
    except KeyError:
        raise ConfigError(f"unknown driver scheme {scheme!r}; known: {', '.join(schemes())}") from None
    module_name, _, class_name = target.partition(":")
    try:
        module = importlib.import_module(module_name)
        cls = getattr(module, class_name)  # a lazy package imports the driver (and its library) here
    except ModuleNotFoundError as exc:
        missing = (exc.name or "").split(".")[0]
        if missing in _PACKAGES:
            package, extra = _PACKAGES[missing]
            raise MissingDependency(
                f"the {scheme}:// driver needs the package {package!r}: pip install 'servoid[{extra}]'"
            ) from exc
        raise
    return cls  # type: ignore[no-any-return]


def extra_for(module: str) -> str | None:
    """The servoid extra that installs the top-level ``module`` (None for one servoid does not know).

    Parameters
    ----------
    module : str
        A module name as ``ModuleNotFoundError.name`` gives it (``"dynamixel_sdk"``).
    """
    found = _PACKAGES.get(module.split(".")[0])
    return None if found is None else found[1]


def driver_from_url(url: str) -> Driver:
    """Build the driver a URL names (not yet open: use it as a context manager).

    A URL that names several servos of one bus (``id=1,2,3``, for ``dxl`` and
    ``feetech``) gives a :class:`~servoid.drivers.bus.BusDriver`, which the
    sampling session runs as one multi-joint measurement; its limits take
    one value per joint (``min=-1,-0.5,-1``) or one for all.

    Parameters
    ----------
    url : str
        A driver URL (see the module docstring for the forms).

    Examples
    --------
    >>> with driver_from_url("sim://xm430?snr=40") as servo:   # doctest: +SKIP
    ...     servo.enable()
    ...     m = servo.exchange(0.5)
    """
    parsed = parse_url(url)
    cls = driver_class(parsed.scheme)
    ids = parsed.options.get("id", "")
    if "," not in ids:
        return cls.from_url(parsed)
    if not hasattr(cls, "group_exchange"):
        raise ConfigError(f"{url}: id={ids} names several servos; only dxl:// and feetech:// run several on one bus")
    import dataclasses

    from servoid.drivers.base import COMMON_OPTIONS
    from servoid.drivers.bus import BusDriver, bus_ids

    servo_ids = bus_ids(ids)
    per_joint = [dict(parsed.options, id=str(servo_id)) for servo_id in servo_ids]
    for name, text in parsed.options.items():
        if name == "id" or "," not in text:
            continue  # one value for every joint
        if name not in COMMON_OPTIONS:
            raise ConfigError(
                f"{url}: {name}={text} has several values; only the limits ({', '.join(COMMON_OPTIONS)}) "
                "take one value per joint"
            )
        values = text.split(",")
        if len(values) != len(servo_ids):
            raise ConfigError(
                f"{url}: {name}={text} has {len(values)} values for {len(servo_ids)} joints (ids {ids}); "
                "give one value for all joints or one per joint, in the order of the ids"
            )
        for options, value in zip(per_joint, values):
            options[name] = value.strip()
    joints = [cls.from_url(dataclasses.replace(parsed, options=options)) for options in per_joint]
    for joint in joints:
        joint.url = url
    return BusDriver(joints, url=url)  # type: ignore[return-value]
