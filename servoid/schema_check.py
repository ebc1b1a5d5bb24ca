"""Checking a parsed JSON document against one of servoid's shipped JSON Schemas, with one line per problem.

servoid ships its file formats as JSON Schemas (``servoid/model.schema.json``)
and checks what it reads against them, so that the schema is the one place
where the format is stated. The checker here understands the part of JSON
Schema (draft 2020-12) those schemas use -- ``type``, ``const``, ``enum``,
``required``, ``properties``, ``additionalProperties``, ``items``,
``minItems``/``maxItems``, ``maxLength``, ``minimum``/``maximum`` and their
exclusive forms -- and refuses a schema with any other keyword, so that an
edit to a schema can never be ignored silently. The test suite holds it
against the ``jsonschema`` package on generated documents. (``jsonschema``
itself takes half a second to import; a command that reads one model file
should not.)
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = ["Problem", "problems", "first_problem", "KEYWORDS", "SchemaUnsupported", "json_path"]

#: Keywords that only annotate (ignored when checking).
_ANNOTATIONS = frozenset({"$schema", "$id", "title", "description", "$comment", "examples", "default"})
#: Keywords this checker applies.
KEYWORDS = frozenset({
    "type", "const", "enum", "required", "properties", "additionalProperties", "items", "minItems", "maxItems",
    "maxLength", "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum",
}) | _ANNOTATIONS  # fmt: skip


class SchemaUnsupported(Exception):
    """A schema uses a keyword this checker does not apply (a bug in servoid, found by its tests)."""


@dataclass(frozen=True)
class Problem:
    """Where a document breaks its schema, and how.

    Attributes
    ----------
    path : tuple
        Keys and indices from the document's root to the offending value.
    message : str
        What is wrong, e.g. ``"(=True) must be a number"``.
    """

    path: tuple[str | int, ...]
    message: str

    def __str__(self) -> str:
        where = json_path(self.path)
        return f"{where} {self.message}" if where else f"the document {self.message}"


def json_path(path: Sequence[str | int]) -> str:
    """``model.a[0]`` for the path ``("model", "a", 0)``."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_type(value: Any, kind: str) -> bool:
    if kind == "null":
        return value is None
    if kind == "boolean":
        return isinstance(value, bool)
    if kind == "object":
        return isinstance(value, Mapping)
    if kind == "array":
        return isinstance(value, list)
    if kind == "string":
        return isinstance(value, str)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    if kind == "number":
        return True
    if kind == "integer":
        return isinstance(value, int) or (math.isfinite(value) and float(value).is_integer())
    raise SchemaUnsupported(f"type {kind!r}")


def _same(a: Any, b: Any) -> bool:
    """JSON equality: 1 equals 1.0, but true is no number."""
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return bool(a == b)
    return type(a) is type(b) and bool(a == b)


def _kinds(kinds: str | list[str]) -> str:
    names = [kinds] if isinstance(kinds, str) else list(kinds)
    article = {"object": "an object", "array": "a list", "integer": "an integer", "null": "null"}
    shown = [article.get(k, f"a {k}") for k in names]
    return shown[0] if len(shown) == 1 else ", ".join(shown[:-1]) + " or " + shown[-1]


def problems(instance: Any, schema: Mapping[str, Any], path: tuple[str | int, ...] = ()) -> Iterator[Problem]:
    """Every place ``instance`` breaks ``schema``, outermost first.

    Parameters
    ----------
    instance : any
        A parsed JSON document (or part of one).
    schema : mapping
        A JSON Schema using only :data:`KEYWORDS`.
    path : tuple
        Where ``instance`` sits in the whole document (for the messages).

    Raises
    ------
    SchemaUnsupported
        If ``schema`` uses a keyword outside :data:`KEYWORDS`.
    """
    unknown = set(schema) - KEYWORDS
    if unknown:
        raise SchemaUnsupported(f"keyword(s) {', '.join(sorted(unknown))} at {json_path(path) or 'the root'}")
    if "type" in schema and not any(_is_type(instance, k) for k in _as_list(schema["type"])):
        yield Problem(path, f"(={_show(instance)}) must be {_kinds(schema['type'])}")
        return
    if "const" in schema and not _same(instance, schema["const"]):
        yield Problem(path, f"(={_show(instance)}) must be {schema['const']!r}")
    if "enum" in schema and not any(_same(instance, option) for option in schema["enum"]):
        yield Problem(path, f"(={_show(instance)}) must be one of {', '.join(map(repr, schema['enum']))}")
    if isinstance(instance, (int, float)) and not isinstance(instance, bool):
        yield from _numbers(instance, schema, path)
    if isinstance(instance, str) and "maxLength" in schema and len(instance) > schema["maxLength"]:
        yield Problem(path, f"({len(instance)} characters) must be at most {schema['maxLength']} long")
    if isinstance(instance, list):
        if "minItems" in schema and len(instance) < schema["minItems"]:
            yield Problem(path, f"(={_show(instance)}) must hold at least {schema['minItems']} item(s)")
        if "maxItems" in schema and len(instance) > schema["maxItems"]:
            yield Problem(path, f"({len(instance)} items) must hold at most {schema['maxItems']}")
        if "items" in schema:
            for i, item in enumerate(instance):
                yield from problems(item, schema["items"], (*path, i))
    if isinstance(instance, Mapping):
        for key in schema.get("required", ()):
            if key not in instance:
                yield Problem(path, f"lacks the required field {key!r}")
        properties = schema.get("properties", {})
        extra = schema.get("additionalProperties", True)
        for key, value in instance.items():
            if key in properties:
                yield from problems(value, properties[key], (*path, key))
            elif extra is False:
                yield Problem(path, f"has a field {key!r} the format does not know (known: {', '.join(properties)})")
            elif isinstance(extra, Mapping):
                yield from problems(value, extra, (*path, key))


def _as_list(kinds: str | list[str]) -> list[str]:
    return [kinds] if isinstance(kinds, str) else list(kinds)


def _numbers(value: float, schema: Mapping[str, Any], path: tuple[str | int, ...]) -> Iterator[Problem]:
    if "minimum" in schema and not value >= schema["minimum"]:
        yield Problem(path, f"(={_show(value)}) must be >= {schema['minimum']}")
    if "exclusiveMinimum" in schema and not value > schema["exclusiveMinimum"]:
        yield Problem(path, f"(={_show(value)}) must be > {schema['exclusiveMinimum']}")
    if "maximum" in schema and not value <= schema["maximum"]:
        yield Problem(path, f"(={_show(value)}) must be <= {schema['maximum']}")
    if "exclusiveMaximum" in schema and not value < schema["exclusiveMaximum"]:
        yield Problem(path, f"(={_show(value)}) must be < {schema['exclusiveMaximum']}")


def first_problem(instance: Any, schema: Mapping[str, Any]) -> Problem | None:
    """The first place ``instance`` breaks ``schema`` (see :func:`problems`), or None when it follows it.

    Parameters
    ----------
    instance : any
        A parsed JSON document.
    schema : mapping
        The schema.
    """
    return next(problems(instance, schema), None)
