"""Extended models (base + effects) in ``model.json``.

An :class:`~servoid.ident.models.extended.ExtendedModel` is saved as an ordinary
``model.json`` (:mod:`servoid.modelfile`, the base model under ``"model"``)
with one more top-level key::

    "effects": [{"name": "coulomb_friction", "parameters": {"force": 0.1}}, ...]

in the order the effects were found. Parameter units are those of
:data:`servoid.ident.models.effects.EFFECTS` (``force``, ``limit``, ``width`` in the
unit of ``u``; ``samples`` in samples; ``pole`` dimensionless). A file
without the key is a model with no effect, so every ``model.json`` loads.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from servoid.errors import ModelError
from servoid.ident.models.extended import ExtendedModel
from servoid.modelfile import ModelFile, load_model, save_model

__all__ = ["EFFECTS_KEY", "save_extended_model", "load_extended_model"]

#: The top-level key of model.json that holds the effects.
EFFECTS_KEY = "effects"


def save_extended_model(path: str | os.PathLike[str], model: ExtendedModel, **fields: Any) -> Path:
    """Write ``model`` as ``model.json``; ``fields`` are further :class:`~servoid.modelfile.ModelFile` fields.

    Examples
    --------
    >>> save_extended_model("model.json", diagnosis.model, method="mrgia+oe+effects", fit_nrmse=0.025)  # doctest: +SKIP
    """
    extra = dict(fields.pop("extra", {}) or {})
    extra[EFFECTS_KEY] = model.effects_json()
    return save_model(path, ModelFile(model=model.base, extra=extra, **fields))


def load_extended_model(path: str | os.PathLike[str]) -> tuple[ExtendedModel, ModelFile]:
    """Read a ``model.json`` as an extended model (no ``"effects"`` key: no effect).

    Returns
    -------
    model : ExtendedModel
    content : ModelFile
        Everything else the file holds (units, provenance).

    Raises
    ------
    DataError
        For a file that is not a servoid model (see :func:`servoid.modelfile.load_model`).
    ModelError
        For an invalid ``"effects"`` entry (named).
    """
    content = load_model(path)
    try:
        model = ExtendedModel.from_json(content.model, content.extra.get(EFFECTS_KEY))
    except ModelError as exc:
        raise ModelError(f"{path}: {exc}") from exc
    return model, content
