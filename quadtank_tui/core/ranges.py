"""One error type for a parameter outside its range, naming the field.

Files map it to file/line/key, the UI puts it next to the field, the CLI prints it.
"""

from __future__ import annotations

import math


class ParameterError(ValueError):
    """A value refused by validation; `field` names the parameter."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.reason = message


def is_finite_number(value: object) -> bool:
    """A real number (not a bool) that is a finite float: False for NaN, inf and a
    whole number too large for a float (math.isfinite raises OverflowError on it)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def check_number(field: str, value: object) -> float:
    """A finite real number (bool is refused: True is not a gain)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(field, f"must be a number, got {value!r}")
    try:
        x = float(value)
    except OverflowError:  # a whole number beyond any float (YAML reads 400 digits as an int)
        raise ParameterError(field, f"must be a finite number, got a whole number of {len(str(abs(value)))} digits") from None
    if not math.isfinite(x):
        raise ParameterError(field, f"must be a finite number, got {value!r}")
    return x


def check_range(
    field: str,
    value: object,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """`value` as float if lo <= value <= hi (strict where *_open); else ParameterError."""
    x = check_number(field, value)
    if lo is not None and (x <= lo if lo_open else x < lo):
        raise ParameterError(field, f"must be {'>' if lo_open else '>='} {lo:g}, got {x:g}")
    if hi is not None and (x >= hi if hi_open else x > hi):
        raise ParameterError(field, f"must be {'<' if hi_open else '<='} {hi:g}, got {x:g}")
    return x


def check_sampling_time(h: object) -> float:
    """A sampling time `h` (s) as float: a finite number > 0, refused as "TSamp"."""
    return check_range("TSamp", h, 0.0, None, lo_open=True)
