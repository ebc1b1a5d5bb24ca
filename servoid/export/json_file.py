"""``--format json``: the canonical ``model.json``, written in the current schema version.

A version 1 file comes out as version 2, with servoid's default smoothing
band (or the one given to :func:`servoid.export.export_model`); everything
else, ``effects`` and unknown keys included, is carried over unchanged.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from servoid.modelfile import ModelFile


__all__ = ["SUMMARY", "OPTIONS", "render"]

SUMMARY = "the model file itself (schema servoid.model, current version), for tools and archives"
OPTIONS: tuple[str, ...] = ()


def render(content: ModelFile) -> str:
    """The JSON text of ``content``."""
    return content.to_json()
