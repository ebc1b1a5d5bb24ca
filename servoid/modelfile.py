"""``model.json``: an identified model and its compensation parameters on disk, versioned.

Schema ``servoid.model``, version 3 (documented field by field, with units, in
``docs/model-schema.md``; machine-readable as the JSON Schema
``servoid/model.schema.json``)::

    {
      "schema": "servoid.model",
      "version": 3,
      "model": {"a": [...], "b": [...], "delay": 1, "m1": 1.0, "m2": ..., "c1": ..., "c2": ...},
      "stderr": {"a1": ..., ..., "c2": ...} | null,
      "units": {"input": "<unit of u>", "output": "<unit of y, x, c1, c2>",
                "time": "sample", "sample_period_s": <float> | null},
      "method": "mrgia" | "mrgia+oe",
      "fit_nrmse": <free-run NRMSE on the identification record> | null,
      "identified": {"at": "<ISO 8601 UTC>", "source": "<sim://... | file | driver URL>",
                     "samples": <int> | null, "servoid_version": "<x.y.z>"},
      "servo": {<identity reported by the driver>} | null,
      "compensation": {"band": <smoothing band of the backlash inverse, output unit>,
                       "noise_std": <output noise it was chosen for, output unit> | null},
      "structure": {"name": "output_backlash" | "play_in_loop", "form": "pseudo_wiener" | "servo_loop",
                    "identifiable": <bool> | null, "reason": "<why not>" | null, "play": <c1 + c2> | null,
                    "play_interval": [<low> | null, <high> | null],
                    "operating_point": {"u": <float>, "y": <float>}, "delta0": <float>,
                    "loop": {<servo-loop parameters>} | null},
      "effects": [<model extension>, ...]          (optional, see docs/diagnose.md)
    }

Units: ``c1``, ``c2`` and the band are in the output unit, ``delay`` in
samples; the output unit is whatever the recording was in (``rad``,
``counts``, or the user's unit, as stated).

Versions: version 1 (no ``compensation``) is still read; its band is then
servoid's default (:func:`servoid.ident.control.compensate.default_band`) and
:attr:`ModelFile.read_version` says so. Versions 1 and 2 (no ``structure``)
read as the output backlash of a pseudo-Wiener model about zero, not judged
(``identifiable`` None). Unknown top-level keys, ``effects``
among them, are kept in :attr:`ModelFile.extra` and written back unchanged.
"""

from __future__ import annotations

import copy
import datetime as _dt
import functools
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid import __version__, limits, validation
from servoid.errors import ConfigError, DataError, ModelError
from servoid.files import read_json
from servoid.schema_check import first_problem, json_path

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.models.pseudo_wiener import BacklashModel

# The model class, the band and the JSON writer (NumPy) are imported where they are used, so that the
# schema's facts (VERSION, SCHEMA) reach the command line's help without loading NumPy.

__all__ = ["SCHEMA", "VERSION", "READABLE_VERSIONS", "EFFECTS_KEY", "ModelFile", "save_model", "load_model",
           "json_schema"]  # fmt: skip

SCHEMA = "servoid.model"
VERSION = 3
#: Versions this servoid reads; it writes :data:`VERSION`.
READABLE_VERSIONS = (1, 2, 3)
#: Top-level key of the optional list of model extensions (docs/diagnose.md).
EFFECTS_KEY = "effects"


@dataclass(frozen=True)
class ModelFile:
    """The content of a ``model.json``.

    Attributes mirror the schema in the module docstring; ``band`` and
    ``noise_std`` are ``compensation.band`` (``None``: servoid's default for
    the model, see :attr:`compensation_band`) and ``compensation.noise_std``
    (the identification's residual RMS), ``read_version`` the version the
    file had when it was read (``None`` for content made in memory). The
    ``structure`` section is ``structure``, ``form``, ``identifiable``
    (``None``: not judged, a file older than version 3), ``reason``,
    ``play``, ``play_interval``, ``operating_point`` (``(u, y)``),
    ``delta0`` and ``loop``.
    """

    model: BacklashModel
    stderr: dict[str, float] | None = None
    input_unit: str = "unit"
    output_unit: str = "unit"
    sample_period_s: float | None = None
    method: str = "mrgia+oe"
    fit_nrmse: float | None = None
    source: str = ""
    samples: int | None = None
    identified_at: str = ""
    servoid_version: str = __version__
    servo: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    band: float | None = None
    noise_std: float | None = None
    read_version: int | None = None
    structure: str = "output_backlash"
    form: str = "pseudo_wiener"
    identifiable: bool | None = None
    reason: str = ""
    play: float | None = None
    play_interval: tuple[float | None, float | None] = (None, None)
    operating_point: tuple[float, float] = (0.0, 0.0)
    delta0: float = 0.0
    loop: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        for name in ("band", "noise_std"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, validation.non_negative(name, getattr(self, name)))

    def __repr__(self) -> str:
        period = f", every {self.sample_period_s:g} s" if self.sample_period_s else ""
        fit = f", fit {100 * (1 - self.fit_nrmse):.2f} %" if self.fit_nrmse is not None else ""
        return f"ModelFile({self.method}{fit}, y in {self.output_unit}{period}; {self.model!r})"

    def to_control(self) -> Any:
        """The linear block as a python-control ``TransferFunction`` with the file's sample period (``dt=True`` when unknown)."""
        return self.model.to_control(self.sample_period_s or True)

    @property
    def compensation_band(self) -> float:
        """The smoothing band of the backlash inverse, output unit (stored, or servoid's default)."""
        from servoid.ident.control.compensate import default_band

        return default_band(self.model, noise_std=self.noise_std) if self.band is None else self.band

    @property
    def effects(self) -> list[Any]:
        """The model extensions stored under ``effects`` (an empty list when there are none)."""
        return list(self.extra.get(EFFECTS_KEY) or [])

    def effect_names(self) -> list[str]:
        """A short name for each entry of :attr:`effects`, for messages."""
        names = []
        for entry in self.effects:
            if isinstance(entry, Mapping):
                label = next((entry[k] for k in ("name", "effect", "kind", "type") if k in entry), None)
                names.append(str(label) if label is not None else "unnamed")
            else:
                names.append(str(entry))
        return names

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the schema."""
        from servoid.ident.serialise import number

        out: dict[str, Any] = {
            "schema": SCHEMA,
            "version": VERSION,
            "model": self.model.to_dict(),
            # JSON has no NaN: a standard error the data do not determine is null
            "stderr": None if self.stderr is None else {k: number(v) for k, v in self.stderr.items()},
            "units": {
                "input": self.input_unit,
                "output": self.output_unit,
                "time": "sample",
                "sample_period_s": self.sample_period_s,
            },
            "method": self.method,
            "fit_nrmse": self.fit_nrmse,
            "identified": {
                "at": self.identified_at or _now(),
                "source": self.source,
                "samples": self.samples,
                "servoid_version": self.servoid_version,
            },
            "servo": self.servo,
            "compensation": {"band": self.compensation_band, "noise_std": self.noise_std},
            "structure": {
                "name": self.structure,
                "form": self.form,
                "identifiable": self.identifiable,
                "reason": self.reason or None,
                "play": number(self.play),
                "play_interval": [number(v) for v in self.play_interval],
                "operating_point": {"u": self.operating_point[0], "y": self.operating_point[1]},
                "delta0": self.delta0,
                "loop": self.loop,
            },  # fmt: skip
        }
        out.update(self.extra)
        return out

    def to_json(self) -> str:
        """The file's text: :meth:`to_dict` pretty-printed, with a final newline."""
        from servoid.ident.serialise import dumps

        return dumps(self.to_dict(), indent=2) + "\n"


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def save_model(path: str | os.PathLike[str], content: ModelFile) -> Path:
    """Write ``content`` as ``model.json`` (pretty-printed, UTF-8); return the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(content.to_json(), encoding="utf-8")
    return p


def load_model(path: str | os.PathLike[str]) -> ModelFile:
    """Read a ``model.json``.

    Everything is checked before it is used: the file's size and nesting
    (:mod:`servoid.limits`), every number finite and within
    :data:`~servoid.limits.MAX_MAGNITUDE` (``NaN`` only where servoid 0.1
    wrote it: version 1's ``stderr``), every string valid Unicode of bounded
    length, the whole document against the shipped JSON Schema
    (:func:`json_schema`), and the model's orders and delay against servoid's
    limits.

    Raises
    ------
    DataError
        Missing file, not JSON, another schema, a version this servoid does
        not know (older files are named as such), missing fields, or a value
        that breaks the schema or a limit (named, with its place in the file).
    ModelError
        The model inside is invalid (the message names the value).
    """
    from servoid.ident.models.pseudo_wiener import BacklashModel
    from servoid.ident.serialise import number

    p = Path(path)
    data = read_json(p, what="model file", max_bytes=limits.MAX_JSON_BYTES, non_finite=True)
    if not isinstance(data, Mapping) or data.get("schema") != SCHEMA:
        found = data.get("schema") if isinstance(data, Mapping) else type(data).__name__
        raise DataError(f"{p}: not a servoid model file (schema {found!r}, expected {SCHEMA!r})")
    version = data.get("version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise DataError(f"{p}: schema version {version!r} is not a version number (this servoid reads {_readable()})")
    if version > VERSION:
        raise DataError(
            f"{p}: schema version {version} is newer than this servoid reads ({_readable()}); upgrade servoid"
        )
    if version not in READABLE_VERSIONS:
        raise DataError(f"{p}: schema version {version} is older than any this servoid reads ({_readable()})")
    required = (
        ("model", "units", "identified")
        + (("compensation",) if version >= 2 else ())
        + (("structure",) if version >= 3 else ())
    )
    for key in required:
        if key not in data:
            raise DataError(f"{p}: missing field {key!r} (required in version {version})")
    _check_values(p, data, version)
    units = _section(p, data, "units")
    ident = _section(p, data, "identified")
    band = noise = None
    if version >= 2:
        comp = _section(p, data, "compensation")
        if "band" not in comp:
            raise DataError(f"{p}: missing field 'compensation.band' (the smoothing band, output unit)")
        try:
            band = validation.non_negative("compensation.band", comp["band"])
            if comp.get("noise_std") is not None:
                noise = validation.non_negative("compensation.noise_std", comp["noise_std"])
        except ConfigError as exc:
            raise DataError(f"{p}: {exc}") from None
    for key in ("stderr", "servo"):
        if data.get(key) is not None and not isinstance(data[key], Mapping):
            raise DataError(f"{p}: {key!r} must be an object or null, got {type(data[key]).__name__}")
    stderr = data.get("stderr")
    if stderr is not None:
        for name, value in stderr.items():
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
                raise DataError(f"{p}: stderr.{name} (={value!r}) must be a number or null")
        # files of servoid 0.1 wrote NaN (not JSON) where the data left a parameter undetermined
        stderr = {k: number(v) for k, v in stderr.items()}
    period = units.get("sample_period_s")
    if period is not None and not (_is_number(period) and period > 0):
        raise DataError(f"{p}: units.sample_period_s (={period!r}) must be a positive number of seconds or null")
    if data.get(EFFECTS_KEY) is not None and not isinstance(data[EFFECTS_KEY], list):
        raise DataError(
            f"{p}: {EFFECTS_KEY!r} must be a list of model extensions (see docs/diagnose.md), "
            f"got {type(data[EFFECTS_KEY]).__name__}"
        )
    # the checks above name the usual slips in their own words; the schema holds the whole format
    problem = first_problem(data, json_schema(version))
    if problem is not None:
        kind = ModelError if problem.path[:1] == ("model",) else DataError  # the model inside, or the file
        raise kind(f"{p}: {problem} (schema {SCHEMA} version {version}, docs/model-schema.md)")
    _check_sizes(p, data["model"])
    try:
        model = BacklashModel.from_dict(data["model"])
    except ModelError as exc:
        raise ModelError(f"{p}: {exc}") from exc
    known = {"schema", "version", "model", "stderr", "units", "method", "fit_nrmse", "identified", "servo",
             "compensation", "structure"}  # fmt: skip
    structure = _structure(data) if version >= 3 else {}
    return ModelFile(
        model=model,
        stderr=stderr,
        input_unit=str(units.get("input", "unit")),
        output_unit=str(units.get("output", "unit")),
        sample_period_s=units.get("sample_period_s"),
        method=str(data.get("method", "")),
        fit_nrmse=data.get("fit_nrmse"),
        source=str(ident.get("source", "")),
        samples=ident.get("samples"),
        identified_at=str(ident.get("at", "")),
        servoid_version=str(ident.get("servoid_version", "")),
        servo=data.get("servo"),
        extra={k: v for k, v in data.items() if k not in known},
        band=band,
        noise_std=noise,
        read_version=version,
        **structure,
    )


def _structure(data: Mapping[str, Any]) -> dict[str, Any]:
    """The ``structure`` section (checked by the schema) as :class:`ModelFile`'s fields."""
    sec = data["structure"]
    point = sec.get("operating_point") or {}
    interval = sec.get("play_interval") or [None, None]
    return {
        "structure": str(sec["name"]), "form": str(sec["form"]), "identifiable": None if sec["identifiable"] is None else bool(sec["identifiable"]),
        "reason": str(sec.get("reason") or ""), "play": sec.get("play"),
        "play_interval": (interval[0], interval[1]),
        "operating_point": (float(point.get("u", 0.0)), float(point.get("y", 0.0))),
        "delta0": float(sec.get("delta0", 0.0)), "loop": sec.get("loop"),
    }  # fmt: skip


@functools.cache
def _schema_text() -> str:
    return resources.files("servoid").joinpath("model.schema.json").read_text(encoding="utf-8")


def json_schema(version: int = VERSION) -> dict[str, Any]:
    """The JSON Schema of a model file of ``version``: the shipped ``model.schema.json`` (version 3).

    Version 2 is the same but for its ``version`` and no ``structure``
    section; version 1 has no ``compensation`` section either.

    Parameters
    ----------
    version : int
        One of :data:`READABLE_VERSIONS`.
    """
    schema: dict[str, Any] = json.loads(_schema_text())
    if version < VERSION:
        schema = copy.deepcopy(schema)
        schema["properties"]["version"] = {"const": version}
        dropped = {"structure"} | ({"compensation"} if version == 1 else set())
        schema["required"] = [key for key in schema["required"] if key not in dropped]
        del schema["properties"]["structure"]
    return schema


def _check_values(path: Path, data: Any, version: int) -> None:
    """Every number finite (NaN only in version 1's stderr) and within the limit; every string valid text."""
    stack: list[tuple[Any, tuple[str | int, ...]]] = [(data, ())]
    while stack:
        node, where = stack.pop()
        if isinstance(node, dict):
            for key, value in node.items():
                _text(path, key, (*where, f"<key {key[:40]!r}>"))
                stack.append((value, (*where, key)))
        elif isinstance(node, list):
            stack.extend((value, (*where, i)) for i, value in enumerate(node))
        elif isinstance(node, str):
            _text(path, node, where)
        elif isinstance(node, (int, float)) and not isinstance(node, bool):
            if isinstance(node, float) and math.isnan(node) and version == 1 and where[:1] == ("stderr",):
                continue  # servoid 0.1 wrote NaN where the data left a parameter undetermined
            try:
                limits.bounded_real(json_path(where), node)
            except ConfigError as exc:
                raise DataError(f"{path}: {exc}") from None


def _text(path: Path, value: str, where: tuple[str | int, ...]) -> None:
    try:
        limits.text(json_path(where) or "a key", value)
    except ConfigError as exc:
        raise DataError(f"{path}: {exc}") from None


def _check_sizes(path: Path, model: Mapping[str, Any]) -> None:
    """The model's orders and delay within servoid's limits (before any work sized by them)."""
    try:
        limits.bounded_count("model.a (its length, na)", len(model["a"]), limit=limits.MAX_ORDER,
                             what="the order of the linear block")  # fmt: skip
        limits.bounded_count("model.b (its length, nb + 1)", len(model["b"]), limit=limits.MAX_ORDER,
                             what="the order of the linear block")  # fmt: skip
        limits.bounded_count("model.delay", model["delay"], limit=limits.MAX_DELAY, what="the delay in samples")
    except ConfigError as exc:
        raise DataError(f"{path}: {exc}") from None


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _readable() -> str:
    return "versions " + ", ".join(map(str, READABLE_VERSIONS))


def _section(path: Path, data: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    """``data[key]`` as an object (``null`` reads as empty), or a one-line DataError."""
    value = data.get(key) or {}
    if not isinstance(value, Mapping):
        raise DataError(f"{path}: {key!r} must be an object, got {type(value).__name__}")
    return value
