"""The model structures by name (where the play sits) and the model forms: the one place these names are defined.

Plain Python, so that ``--help`` texts and the model file's schema can name
them without loading NumPy.

Structures (where the play sits relative to the drive's position loop):

``output_backlash``
    The play outside the loop: the drive closes its position loop on the motor
    side and the output encoder reads the load through the play. The paper's
    pseudo-Wiener structure (a linear block, then an output backlash).
``play_in_loop``
    The play inside the position loop: the encoder sits on the load (a
    Dynamixel's or Feetech's horn) and the loop is closed around the play. The
    motor keeps moving while the load waits in the play, so the play changes
    the loop's dynamics rather than offsetting its output.

Forms (the model that describes a structure):

``pseudo_wiener``
    The paper's black box (:mod:`servoid.ident.models.pseudo_wiener`); output backlash only.
``servo_loop``
    The grey-box servo loop (:mod:`servoid.ident.models.servo_loop`): position P
    over velocity P(I) over the motor with friction, the play fed back from
    the motor side or from the load; either structure.
"""

from __future__ import annotations

__all__ = [
    "OUTPUT_BACKLASH",
    "PLAY_IN_LOOP",
    "STRUCTURES",
    "STRUCTURE_SUMMARIES",
    "PSEUDO_WIENER",
    "SERVO_LOOP",
    "FORMS",
    "FEEDBACK",
]

OUTPUT_BACKLASH = "output_backlash"
PLAY_IN_LOOP = "play_in_loop"

#: One line per structure, for reports and ``--help``.
STRUCTURE_SUMMARIES: dict[str, str] = {
    OUTPUT_BACKLASH: "the play outside the position loop (loop closed on the motor side, output read through the play)",
    PLAY_IN_LOOP: "the play inside the position loop (loop closed on the load's encoder, around the play)",
}

#: Every structure name, in the order reports list them.
STRUCTURES: tuple[str, ...] = tuple(STRUCTURE_SUMMARIES)

PSEUDO_WIENER = "pseudo_wiener"
SERVO_LOOP = "servo_loop"

#: Every model form.
FORMS: tuple[str, ...] = (PSEUDO_WIENER, SERVO_LOOP)

#: The servo-loop model's feedback (what its position loop reads) for each structure.
FEEDBACK: dict[str, str] = {OUTPUT_BACKLASH: "motor", PLAY_IN_LOOP: "load"}
