"""Showing and reading numbers the way the windows and widgets need them.

One place decides how a parameter value looks on screen and how typed text turns
back into a value, so a value shown, edited unchanged and set again is the same.
"""

from __future__ import annotations

import math
from enum import Enum
from typing import Any

from quadtank_tui.core.ranges import ParameterError


def fmt(value: Any) -> str:
    """A parameter value as text: numbers with up to 6 significant digits
    (0.3 -> "0.3", 3.0 -> "3", 62.16 -> "62.16"), flags as on/off."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, Enum):
        return str(value.value)
    if isinstance(value, float):
        if value == 0.0:
            return "0"
        return f"{value:.6g}"
    if isinstance(value, tuple):
        return " ".join(str(v) for v in value)
    return str(value)


def fixed(value: float, decimals: int = 3) -> str:
    """A measured value with a fixed number of decimals (levels, inputs), so the
    columns of a live display do not jump about."""
    if not math.isfinite(value):
        return "  nan"
    text = f"{value:.{decimals}f}"
    return "0." + "0" * decimals if text == "-0." + "0" * decimals else text


def parse_number(key: str, text: str) -> float:
    """Typed text as a number; ParameterError naming `key` if it is not one.

    A comma is accepted as the decimal sign (students type 0,3 as often as 0.3).
    """
    cleaned = text.strip().replace(",", ".")
    try:
        value = float(cleaned)
    except ValueError:
        raise ParameterError(key, f"{text.strip() or 'nothing'!r} is not a number") from None
    if not math.isfinite(value):
        raise ParameterError(key, f"must be a finite number, got {text.strip()!r}")
    return value
