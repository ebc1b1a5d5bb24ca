"""``model.json``: an identified model on disk, versioned.

Schema ``servoid.model``, version 1::

    {
      "schema": "servoid.model",
      "version": 1,
      "model": {"a": [...], "b": [...], "delay": 1, "m1": 1.0, "m2": ..., "c1": ..., "c2": ...},
      "stderr": {"a1": ..., ..., "c2": ...} | null,
      "units": {"input": "<unit of u>", "output": "<unit of y, x, c1, c2>",
                "time": "sample", "sample_period_s": <float> | null},
      "method": "mrgia" | "mrgia+oe",
      "fit_nrmse": <free-run NRMSE on the identification record>,
      "identified": {"at": "<ISO 8601 UTC>", "source": "<sim://... | file | driver URL>",
                     "samples": <int>, "servoid_version": "<x.y.z>"},
      "servo": {<identity reported by the driver>} | null
    }

Units: ``c1`` and ``c2`` are in the output unit, ``delay`` in samples; the
output unit is whatever the recording was in (``rad``, ``counts``, or the
user's unit, as stated).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Mapping

from servoid import __version__
from servoid.errors import DataError, ModelError
from servoid.ident.model import BacklashModel

__all__ = ["SCHEMA", "VERSION", "ModelFile", "save_model", "load_model"]

SCHEMA = "servoid.model"
VERSION = 1


@dataclass(frozen=True)
class ModelFile:
    """The content of a ``model.json``.

    Attributes mirror the schema in the module docstring.
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

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the schema."""
        out: dict[str, Any] = {
            "schema": SCHEMA,
            "version": VERSION,
            "model": self.model.to_dict(),
            "stderr": self.stderr,
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
        }
        out.update(self.extra)
        return out


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def save_model(path: str | os.PathLike[str], content: ModelFile) -> Path:
    """Write ``content`` as ``model.json`` (pretty-printed, UTF-8); return the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(content.to_dict(), indent=2) + "\n", encoding="utf-8")
    return p


def load_model(path: str | os.PathLike[str]) -> ModelFile:
    """Read a ``model.json``.

    Raises
    ------
    DataError
        Missing file, not JSON, another schema, a version this servoid does
        not know (older files are named as such), or missing fields.
    ModelError
        The model inside is invalid (the message names the value).
    """
    p = Path(path)
    if not p.is_file():
        raise DataError(f"{p}: no such model file")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{p}: not a JSON file ({exc})") from exc
    if not isinstance(data, Mapping) or data.get("schema") != SCHEMA:
        found = data.get("schema") if isinstance(data, Mapping) else type(data).__name__
        raise DataError(f"{p}: not a servoid model file (schema {found!r}, expected {SCHEMA!r})")
    version = data.get("version")
    if version != VERSION:
        if isinstance(version, int) and version > VERSION:
            raise DataError(f"{p}: schema version {version} is newer than this servoid reads ({VERSION}); upgrade servoid")
        raise DataError(f"{p}: schema version {version!r} is not supported (this servoid reads version {VERSION})")
    for key in ("model", "units", "identified"):
        if key not in data:
            raise DataError(f"{p}: missing field {key!r}")
    try:
        model = BacklashModel.from_dict(data["model"])
    except ModelError as exc:
        raise ModelError(f"{p}: {exc}") from exc
    units = data["units"] or {}
    ident = data["identified"] or {}
    known = {"schema", "version", "model", "stderr", "units", "method", "fit_nrmse", "identified", "servo"}
    return ModelFile(
        model=model,
        stderr=data.get("stderr"),
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
    )
