"""``--format yaml``: a ROS 2 parameter file.

The shape ``ros2 run ... --ros-args --params-file FILE`` loads::

    backlash_compensator:            # the node name (--node), or /** for every node
      ros__parameters:
        schema: servoid.model
        schema_version: 2
        units: {input: ..., output: ..., time: sample, sample_period_s: ...}
        backlash: {m1: 1.0, m2: ..., c1: ..., c2: ..., band: ...}
        stderr: {a1: ..., ..., c2: ...}
        linear: {a: [...], b: [...], delay: 1}
        identified: {at: ..., source: ..., samples: ..., method: ..., fit_nrmse: ..., servoid_version: ...}
        servo: {...}

ROS 2 parameters have no null and no empty or mixed-type arrays, and their
names are letters, digits and ``_``: unknown values are left out, mixed
arrays become strings, and other characters in the servo identity's keys
become ``_``. Nested maps are the usual dotted parameter names
(``backlash.c1``).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from typing import Any

from servoid import __version__
from servoid.errors import ConfigError
from servoid.export._text import one_line, visible
from servoid.modelfile import SCHEMA, VERSION, ModelFile

__all__ = ["SUMMARY", "OPTIONS", "DEFAULT_NODE", "render", "ros_parameters"]

SUMMARY = "a ROS 2 parameter file (node: ros__parameters: ...), for a compensator node"
OPTIONS = ("node", "source_name")
DEFAULT_NODE = "backlash_compensator"

_NODE = re.compile(r"(/\*\*|/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*)\Z")
_KEY_BAD = re.compile(r"[^A-Za-z0-9_]")


@functools.cache
def _dumper() -> Any:
    """A YAML dumper with block maps but arrays on one line (``a: [0.45, 0.55]``), as ROS 2 examples write them.

    Made on first use: PyYAML is imported only when a YAML file is written.
    """
    import yaml

    class Dumper(yaml.SafeDumper):
        pass

    Dumper.add_representer(
        list, lambda dumper, data: dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True)
    )
    return Dumper


def _key(name: Any) -> str:
    key = _KEY_BAD.sub("_", str(name)) or "_"
    return key if not key[0].isdigit() else "_" + key


def _value(value: Any) -> Any:
    """``value`` as a ROS 2 parameter value, or ``None`` to leave it out."""
    if value is None:
        return None
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, str):
        return visible(value)  # no bidirectional control reorders what a reader of the file sees
    if isinstance(value, Mapping):
        out = {_key(k): v for k, v in ((k, _value(v)) for k, v in value.items()) if v is not None}
        return out or None
    if isinstance(value, (list, tuple)):
        items = [_value(v) for v in value]
        items = [v for v in items if v is not None and not isinstance(v, dict)]
        if not items:
            return None
        kinds = {type(v) for v in items}
        if kinds == {int, float}:
            return [float(v) for v in items]
        return items if len(kinds) == 1 else [str(v) for v in items]
    return str(value)


def ros_parameters(content: ModelFile) -> dict[str, Any]:
    """The ``ros__parameters`` map of ``content`` (ROS 2 types only)."""
    model = content.model
    params: dict[str, Any] = {
        "schema": SCHEMA,
        "schema_version": VERSION,
        "units": {
            "input": content.input_unit,
            "output": content.output_unit,
            "time": "sample",
            "sample_period_s": content.sample_period_s,
        },
        "backlash": {
            "m1": model.m1,
            "m2": model.m2,
            "c1": model.c1,
            "c2": model.c2,
            "band": content.compensation_band,
        },
        "stderr": content.stderr,
        "linear": {"a": [float(v) for v in model.a], "b": [float(v) for v in model.b], "delay": model.delay},
        "identified": {
            "at": content.identified_at,
            "source": content.source,
            "samples": content.samples,
            "method": content.method,
            "fit_nrmse": content.fit_nrmse,
            "servoid_version": content.servoid_version,
        },
        "servo": content.servo,
    }
    from servoid.loop_compensation import has_loop

    if has_loop(content):
        from servoid.ident.models.structure_names import PLAY_IN_LOOP
        from servoid.loop_compensation import loop_model, reversal_lead

        params["structure"] = content.structure
        params["servo_loop"] = loop_model(content).params()
        if content.structure == PLAY_IN_LOOP:
            # the compensator for a play inside the loop: the backlash section above does not apply
            params["reversal_lead"] = reversal_lead(content).to_dict()
    return _value(params)  # type: ignore[no-any-return]


def render(content: ModelFile, *, node: str = DEFAULT_NODE, source_name: str = "model.json") -> str:
    """The parameter file's text, with a comment header stating the units.

    Parameters
    ----------
    content : ModelFile
        The model (its smoothing band included).
    node : str
        Node name (``name`` or ``/namespace/name``), or ``/**`` for every node.
    source_name : str
        The model file's name, for the comment header.

    Raises
    ------
    ConfigError
        If ``node`` is not a ROS 2 node name.
    """
    if not _NODE.match(node):
        raise ConfigError(
            f"node (={node!r}) must be a ROS 2 node name (letters, digits, _; optional /namespace/) or /**"
        )
    period = content.sample_period_s
    out_unit, in_unit, source = (one_line(t) for t in (content.output_unit, content.input_unit, source_name))
    header = (
        f"# Backlash compensation parameters, generated by servoid {__version__} from {source}.\n"
        f"# Units: backlash.c1, backlash.c2, backlash.band in {out_unit}; linear.b in {out_unit} per {in_unit};\n"
        f"# time in samples (sample period {f'{period:g} s' if period else 'not known'}).\n"
        "# backlash: up line y = x - c1, down line y = m2 (x + c2); band: smoothing band of the inverse.\n"
    )
    import yaml

    body = yaml.dump({node: {"ros__parameters": ros_parameters(content)}}, Dumper=_dumper(), sort_keys=False,
                     default_flow_style=False, allow_unicode=True, width=100)  # fmt: skip
    return header + body
