"""What a user types into the Design screen's lambda and Ms boxes.

    λ   15 30 60          seconds
        T/4 T/2 T         multiples of the model's time constant T
        2L 4L 8L          or of its dead time L (an integrating model has no T)
    Ms  1.6 1.4 1.2       maximum sensitivities (> 1)

Values are separated by spaces or commas (`2 T` is two values); `0.5T`, `0.5*T`
and `T/2` are the same.  T and L are those of the model's first-order
approximation (the lambda method's own, core.design.lambda_tuning.first_order).
A bad entry raises InputError with one line saying which value and why; nothing
is designed then.
"""

from __future__ import annotations

import math
import re

MAX_VALUES = 6
#: Ms above this is no robustness bound at all (Andersson used 1.2 to 2).
MS_MAX = 4.0

_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_LAMBDA = re.compile(rf"^(?P<k>{_NUMBER})?\*?(?P<unit>[TL])?(?:/(?P<d>{_NUMBER}))?$")


class InputError(ValueError):
    """A typed lambda or Ms list that cannot be used: the message says which value."""


def _tokens(text: str) -> list[str]:
    """The values typed, separated by spaces or commas (`T / 4` is one)."""
    text = re.sub(r"\s*([*/])\s*", r"\1", text.strip())
    return [t for t in re.split(r"[\s,;]+", text) if t]


def _count(values: list[float], what: str) -> tuple[float, ...]:
    if not values:
        raise InputError(f"{what}: type at least one value")
    if len(values) > MAX_VALUES:
        raise InputError(f"{what}: at most {MAX_VALUES} values (typed {len(values)})")
    return tuple(dict.fromkeys(values))  # each once, in the order typed


def parse_lambdas(text: str, T: float, L: float) -> tuple[float, ...]:
    """The lambdas in seconds; `T` and `L` (s) stand for the model's time constant and
    dead time (0: the model has none, and a multiple of it is refused)."""
    out = []
    for token in _tokens(text):
        m = _LAMBDA.match(token)
        if m is None or (m["k"] is None and m["unit"] is None):
            raise InputError(f"λ: '{token}' is not a time: type seconds (20 40) or multiples of T or L "
                             "(T/4 0.5T 2L)")
        k = float(m["k"]) if m["k"] is not None else 1.0
        d = float(m["d"]) if m["d"] is not None else 1.0
        if d == 0.0:
            raise InputError(f"λ: '{token}' divides by zero")
        unit = m["unit"]
        base = {"T": T, "L": L, None: 1.0}[unit]
        if base <= 0.0:
            has = "no time constant T (it is integrating)" if unit == "T" else "no dead time L"
            raise InputError(f"λ: '{token}': the model has {has}; type seconds")
        lam = k * base / d
        if not (math.isfinite(lam) and lam > 0.0):
            raise InputError(f"λ: '{token}' must be a time > 0 s")
        out.append(lam)
    return _count(out, "λ")


def parse_ms(text: str) -> tuple[float, ...]:
    """The Ms values, each in (1, MS_MAX]."""
    out = []
    for token in _tokens(text):
        try:
            ms = float(token)
        except ValueError:
            raise InputError(f"Ms: '{token}' is not a number (e.g. 1.4)") from None
        if not (math.isfinite(ms) and 1.0 < ms <= MS_MAX):
            raise InputError(f"Ms: {token} is out of range: Ms is > 1 (1.2 robust .. 2 fast) and at most {MS_MAX:g}")
        out.append(ms)
    return _count(out, "Ms")


def format_values(values: tuple[float, ...] | list[float]) -> str:
    """Values for a box, 3 significant digits: `15.7 31.4 62.7`."""
    return " ".join(f"{v:.3g}" for v in values)
