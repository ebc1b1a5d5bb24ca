"""Parsers for URL options: text in, a checked value out, ``ValueError`` saying what is expected.

Give them to :class:`~servoid.drivers.base.Option`; the base turns the
``ValueError`` into a one-line :class:`~servoid.errors.ConfigError` that
names the URL, the option and its help text.
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["number", "integer", "choice"]


def number(
    *, low: float = -math.inf, high: float = math.inf, low_open: bool = False, what: str = "a number"
) -> Callable[[str], float]:
    """A finite float in ``[low, high]`` (``(low, high]`` with ``low_open``)."""
    left = "(" if low_open else "["

    def parse(text: str) -> float:
        value = float(text)
        if not math.isfinite(value) or value < low or value > high or (low_open and value == low):
            raise ValueError(f"must be {what} in {left}{low:g}, {high:g}]")
        return value

    return parse


def integer(*, minimum: int = 0) -> Callable[[str], int]:
    """A decimal integer ``>= minimum``."""

    def parse(text: str) -> int:
        value = int(text)
        if value < minimum:
            raise ValueError(f"must be an integer >= {minimum}")
        return value

    return parse


def choice(*values: str) -> Callable[[str], str]:
    """One of ``values``."""

    def parse(text: str) -> str:
        if text not in values:
            raise ValueError(f"choose one of {', '.join(values)}")
        return text

    return parse
