"""Validation helpers of the parameter model: each refusal is a ParameterError
naming the key, so a file or a window can say where the bad value is."""

from __future__ import annotations

from enum import Enum
from typing import Any

from quadtank_tui.core.controllers.signals import Wave, WaveParams
from quadtank_tui.core.ranges import ParameterError, check_number, check_range


def enum_value(key: str, enum: type[Enum], value: Any) -> Any:
    """`value` as a member of `enum` (a member or its value)."""
    if isinstance(value, enum):
        return value
    try:
        return enum(value)
    except ValueError:
        allowed = ", ".join(str(m.value) for m in enum)
        raise ParameterError(key, f"must be one of {allowed}; got {value!r}") from None


def whole(key: str, value: Any) -> int:
    """A number with no fractional part, as an int."""
    x = check_number(key, value)
    if x != int(x):
        raise ParameterError(key, f"must be a whole number, got {x:g}")
    return int(x)


def integer(key: str, value: Any, lo: int, hi: int) -> int:
    """A whole number in [lo, hi]."""
    return int(check_range(key, whole(key, value), lo, hi))


def check_period(section: str, ref: WaveParams, tsamp_ms: float) -> None:
    """Refuse a period the sampling time cannot render (thesis 5.4: below twice the
    sampling time the original silently produced a constant)."""
    key = f"{section}.Period"
    if ref.wave is Wave.PRBS:
        if ref.period < 1 or ref.period != int(ref.period):
            raise ParameterError(key, f"a PRBS period is a whole number of samples >= 1, got {ref.period:g}")
    elif ref.period < 2 * tsamp_ms / 1000.0:
        raise ParameterError(
            key, f"{ref.period:g} s is shorter than twice the sampling time ({tsamp_ms / 1000.0:g} s): "
            f"the shortest allowed is {2 * tsamp_ms / 1000.0:g} s"
        )
