"""Export formats of a ``model.json``: what a controller needs, in the formats its world uses.

``json``  the canonical ``model.json`` (schema ``servoid.model``, current version)
``c``     a C99 header: the parameters as ``static const`` and the smoothed
          backlash inverse as an inline function, for firmware
``yaml``  a ROS 2 parameter file (``node: ros__parameters: {...}``)

Each format is a module with ``render(content, **options) -> str``;
:func:`export_model` checks what the model holds against what the format
can express (the ``effects`` list of extended models) before rendering.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from servoid.errors import ConfigError, ModelError
from servoid.export import c_header, json_file, ros2_yaml
from servoid.modelfile import EFFECTS_KEY, ModelFile

__all__ = ["Format", "FORMATS", "export_model"]


@dataclass(frozen=True)
class Format:
    """One export format.

    Attributes
    ----------
    name : str
        What ``--format`` takes.
    suffix : str
        File name suffix.
    summary : str
        One line for ``--help``.
    render : callable
        ``render(content, **options) -> str``.
    options : tuple of str
        The keyword options ``render`` takes.
    expresses_effects : bool
        Whether the format can carry the ``effects`` list of an extended model.
    """

    name: str
    suffix: str
    summary: str
    render: Callable[..., str]
    options: tuple[str, ...]
    expresses_effects: bool


FORMATS: dict[str, Format] = {
    f.name: f
    for f in (
        Format("json", ".json", json_file.SUMMARY, json_file.render, json_file.OPTIONS, True),
        Format("c", ".h", c_header.SUMMARY, c_header.render, c_header.OPTIONS, False),
        Format("yaml", ".yaml", ros2_yaml.SUMMARY, ros2_yaml.render, ros2_yaml.OPTIONS, False),
    )
}


def export_model(
    content: ModelFile,
    fmt: str,
    *,
    band: float | None = None,
    ignore_effects: bool = False,
    source_name: str | None = None,
    **options: Any,
) -> str:
    """Render ``content`` in format ``fmt``.

    Parameters
    ----------
    content : ModelFile
        The model file's content.
    fmt : {"json", "c", "yaml"}
        The format.
    band : float, optional
        Smoothing band of the inverse (output unit), instead of the file's.
    ignore_effects : bool
        Export the backlash model of an extended model (one with ``effects``)
        in a format that cannot express the extensions, leaving them out.
    source_name : str, optional
        The model file's name, for formats that cite it in a comment.
    **options
        Options of the format (see its module); unknown ones are rejected.

    Raises
    ------
    ConfigError
        Unknown format or option, a negative band.
    ModelError
        The model has ``effects`` the format cannot express and
        ``ignore_effects`` is not set.
    """
    if fmt not in FORMATS:
        raise ConfigError(f"format (={fmt!r}) must be one of {', '.join(FORMATS)}")
    spec = FORMATS[fmt]
    unknown = sorted(k for k, v in options.items() if v is not None and k not in spec.options)
    if unknown:
        raise ConfigError(f"option(s) {', '.join(unknown)} do not apply to --format {fmt}")
    names = content.effect_names()
    if names and not spec.expresses_effects and not ignore_effects:
        raise ModelError(
            f"the model has {len(names)} extension(s) in {EFFECTS_KEY!r} ({', '.join(names)}) that the "
            f"{fmt} format cannot express; export the plain backlash model without them with --ignore-effects"
        )
    if band is not None:
        content = dataclasses.replace(content, band=band)
    given = {k: v for k, v in options.items() if v is not None}
    if source_name is not None and "source_name" in spec.options:
        given["source_name"] = source_name
    return spec.render(content, **given)
