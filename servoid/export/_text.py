"""Text from a model file made safe to put in an exported file: one line, every invisible control shown.

A unit, a source path or a servo's identity comes from the model file and
ends up in C comments and YAML. Bidirectional controls (U+202A..U+202E,
U+2066..U+2069, ...) reorder what a reader sees of the code around them (a
"Trojan Source" attack) and make ``gcc -Werror`` fail (``-Wbidi-chars``);
other control characters break lines or terminals. Each is shown as
``<U+202E>``, which every reader and compiler takes as plain text.
"""

from __future__ import annotations

import unicodedata
from typing import Any

__all__ = ["visible", "one_line"]

#: Characters that reorder text: the explicit embeddings, overrides, isolates and marks.
BIDI_CONTROLS = frozenset("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def _shown(ch: str) -> str:
    if ch in BIDI_CONTROLS or (unicodedata.category(ch) in ("Cc", "Cf", "Zl", "Zp") and ch not in "\t"):
        return f"<U+{ord(ch):04X}>"
    return ch


def visible(text: Any) -> str:
    """``text`` with every control, format and bidirectional character written as ``<U+XXXX>``.

    Parameters
    ----------
    text : any
        The text (``str()`` of anything else).
    """
    value = str(text)
    return "".join(_shown(ch) for ch in value) if not value.isprintable() or BIDI_CONTROLS & set(value) else value


def one_line(text: Any) -> str:
    """``text`` on one line (runs of white space as one space), controls shown (:func:`visible`).

    Parameters
    ----------
    text : any
        The text.
    """
    return visible(" ".join(str(text).split()))
