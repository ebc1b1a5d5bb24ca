"""The servo behind a simulated device, by name: a physical twin preset, or one of the estimator's own plants.

Every simulated device -- ``sim://``, the serial firmware's simulated motor,
the CiA 402 and ODrive drives, the Dynamixel emulator -- runs one of these:

==========  ================================================================
name        what
==========  ================================================================
``xm430``   ROBOTIS Dynamixel XM430-W350 twin (:mod:`servoid.drivers.twin.presets`)
``sts3215`` Feetech STS3215 twin
``cia402``  industrial CiA 402 drive twin (motor and load encoder, planetary gear)
``odrive``  ODrive v3.6 twin (reducer, motor and load encoder)
``model``   :data:`~servoid.drivers.model_plant.MODEL_PLANT`: the pseudo-Wiener model
            itself, for exact tests of a transport and of the estimator
``paper``   the paper's Section 4 plant (unitless)
``gear``    the paper's plant with a new gear, ``c1 + c2 = 1`` (the wear scenarios)
==========  ================================================================

A twin takes overrides of any of its parameters by name (text accepted, as
from a URL: ``play_deg=0.8``); a pseudo-Wiener plant takes none. The text
form ``NAME?key=value&...`` (the ``--servo`` option of ``servoid
emulate``) reads like a ``sim://`` URL. The default is a twin everywhere:
it is what a user meets on a bench; the pseudo-Wiener plants are asked for
by name. The names and the defaults are plain facts in
:mod:`servoid.drivers.servo_facts` (what the command line's help reads).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qsl

from servoid.drivers.model_plant import MODEL_AMPLITUDE, MODEL_PLANT, MODEL_UNIT
from servoid.drivers.servo_facts import DEFAULT_RATE_HZ, DEFAULT_SERVO, TWIN_AMPLITUDE_RAD
from servoid.drivers.twin.params import ALIASES, TwinParams
from servoid.drivers.twin.presets import preset, preset_names
from servoid.errors import ConfigError
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.wear import GEAR_PLANT
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE, PAPER_PLANT

__all__ = [
    "Servo",
    "servo",
    "parse_servo",
    "servo_names",
    "twin_option_names",
    "MODEL_PLANTS",
    "DEFAULT_SERVO",
    "TWIN_AMPLITUDE_RAD",
    "DEFAULT_RATE_HZ",
]


@dataclass(frozen=True)
class _ModelPlant:
    model: BacklashModel
    unit: str
    amplitude: float


#: The pseudo-Wiener plants by name: (model, unit, amplitude of its reference input).
MODEL_PLANTS: dict[str, _ModelPlant] = {
    "model": _ModelPlant(MODEL_PLANT, MODEL_UNIT, MODEL_AMPLITUDE),
    "paper": _ModelPlant(PAPER_PLANT, "unit", PAPER_INPUT_AMPLITUDE),
    "gear": _ModelPlant(GEAR_PLANT, "unit", PAPER_INPUT_AMPLITUDE),
}


@dataclass(frozen=True)
class Servo:
    """The servo a simulated device runs: exactly one of ``twin`` and ``model`` is set.

    Attributes
    ----------
    name : str
        Its name (``"xm430"``, ``"model"``, ...).
    twin : TwinParams or None
        A physical twin's parameters, overrides applied.
    model : BacklashModel or None
        A pseudo-Wiener plant.
    unit : str
        Unit of its command and position (``"rad"`` at the output for a twin).
    amplitude : float
        Half-width of the uniform input it is meant to be excited with, ``unit``.
    overrides : dict
        The twin parameters given by name, as given (for a device's identity).
    """

    name: str
    twin: TwinParams | None
    model: BacklashModel | None
    unit: str
    amplitude: float
    overrides: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def is_twin(self) -> bool:
        """Whether this is a physical twin (else a pseudo-Wiener plant)."""
        return self.twin is not None

    def describe(self) -> str:
        """One line: the servo and its overrides."""
        if self.twin is None:
            m = self.model
            assert m is not None
            return (
                f"{self.name}: pseudo-Wiener plant a={m.a} b={m.b} delay={m.delay} m2={m.m2:g} "
                f"c1={m.c1:g} c2={m.c2:g} {self.unit}"
            )
        extra = "".join(f", {k}={v}" for k, v in self.overrides.items())
        return f"{self.name}: {self.twin.description}{extra}"


def servo_names() -> tuple[str, ...]:
    """Every name :func:`servo` accepts: the twin presets, then the pseudo-Wiener plants."""
    return preset_names() + tuple(MODEL_PLANTS)


def twin_option_names() -> tuple[str, ...]:
    """The names a twin's parameters may be overridden by (fields and aliases)."""
    fields = [f.name for f in dataclasses.fields(TwinParams) if f.name not in ("name", "description")]
    return tuple(sorted([*fields, *ALIASES, "encoder_noise_counts"]))


def servo(name: str | None = None, **overrides: Any) -> Servo:
    """The servo called ``name`` (default :data:`DEFAULT_SERVO`), with a twin's parameters overridden.

    Parameters
    ----------
    name : str, optional
        One of :func:`servo_names` (case does not matter).
    **overrides
        Twin parameters by name (:func:`twin_option_names`); text is parsed.

    Raises
    ------
    ConfigError
        An unknown name, an override of a pseudo-Wiener plant, or a bad override (one line, naming it).
    """
    key = DEFAULT_SERVO if name in (None, "") else str(name).strip().lower()
    if key in MODEL_PLANTS:
        if overrides:
            raise ConfigError(
                f"servo {key!r} is the pseudo-Wiener plant and takes no parameters "
                f"(got {', '.join(sorted(overrides))}); the twins ({', '.join(preset_names())}) take them"
            )
        plant = MODEL_PLANTS[key]
        return Servo(key, None, plant.model, plant.unit, plant.amplitude)
    if key not in preset_names():
        raise ConfigError(f"unknown servo {name!r}; valid: {', '.join(servo_names())}")
    unknown = sorted(set(overrides) - set(twin_option_names()))
    if unknown:
        raise ConfigError(
            f"unknown twin parameter(s) {', '.join(unknown)} for servo {key!r}; valid: {', '.join(twin_option_names())}"
        )
    return Servo(key, preset(key, **overrides), None, "rad", TWIN_AMPLITUDE_RAD, dict(overrides))


def parse_servo(text: str | None) -> Servo:
    """A servo from its text form ``NAME?key=value&...`` (the ``--servo`` option; ``NAME`` alone is fine).

    Parameters
    ----------
    text : str or None
        ``"xm430"``, ``"xm430?play_deg=0.8&load_inertia_kgm2=1e-3"``, ``"model"``; None or empty: the default.
    """
    if text is None:
        return servo()
    name, _, query = str(text).partition("?")
    options: dict[str, str] = {}
    for key, value in parse_qsl(query, keep_blank_values=True, strict_parsing=False):
        if key in options:
            raise ConfigError(f"servo {text!r}: option {key!r} is given twice")
        options[key] = value
    return servo(name or None, **options)
