"""The servo-loop model of a ``model.json`` and its reversal lead: what export and compensate use for a play in the loop.

A model file whose ``structure.form`` is ``servo_loop`` stores the loop's
parameters in ``structure.loop`` (:data:`servoid.ident.models.servo_loop.PARAM_NAMES`,
in the output unit and seconds) and its host period in ``units.sample_period_s``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from servoid.errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.control.reversal_lead import ReversalLead
    from servoid.ident.models.servo_loop import ServoLoopModel
    from servoid.modelfile import ModelFile

__all__ = ["has_loop", "loop_model", "reversal_lead"]


def has_loop(content: ModelFile) -> bool:
    """Whether the file holds a servo-loop model (``structure.form`` servo_loop with its parameters).

    Parameters
    ----------
    content : ModelFile
        A model file's content.
    """
    from servoid.ident.models.structure_names import SERVO_LOOP

    return content.form == SERVO_LOOP and bool(content.loop)


def loop_model(content: ModelFile) -> ServoLoopModel:
    """The servo-loop model stored in ``content`` (``structure.loop`` and the sample period).

    Parameters
    ----------
    content : ModelFile
        A model file's content with a servo-loop model (:func:`has_loop`).

    Raises
    ------
    ModelError
        The file holds no servo-loop model, or its parameters are not one.
    """
    from servoid.errors import ConfigError
    from servoid.ident.models.servo_loop import KERNEL_NAMES, PARAM_NAMES, ServoLoopModel

    if not has_loop(content) or content.loop is None:
        raise ModelError("the model file holds no servo-loop model (structure.form is not servo_loop)")
    # the load's parameters (mu, e, al) are optional: absent, the load is massless
    values = {name: content.loop[name] for name in KERNEL_NAMES if name in content.loop}
    missing = [name for name in PARAM_NAMES if name not in values]
    if missing:
        raise ModelError(f"structure.loop lacks {', '.join(missing)}")
    try:
        return ServoLoopModel(structure=content.structure, sample_period_s=content.sample_period_s or 1.0, **values)
    except ConfigError as exc:
        raise ModelError(f"structure.loop is not a servo-loop model: {exc}") from None


def reversal_lead(content: ModelFile, band: float | None = None) -> ReversalLead:
    """The reversal lead for the file's servo-loop model: its ``c1``, ``c2``, ended by the band.

    Parameters
    ----------
    content : ModelFile
        A model file's content with a servo-loop model.
    band : float, optional
        The load's movement that ends a lead (default: the file's compensation band, or 5 % of
        the play when that is 0).
    """
    from servoid.ident.control.reversal_lead import ReversalLead

    model = loop_model(content)
    threshold = content.compensation_band if band is None else band
    if not threshold > 0.0:
        threshold = 0.05 * max(model.play, 1e-12)
    return ReversalLead.for_model(model, threshold)
