"""The controllers of `quadtank icad` as (numerator, denominator) in s, volts per volt:
typed ones (--k1/--k2) read by the program's one model parser (core/design/expr.py),
or the .par file's diagonal elements converted.  ICAD works on rational functions,
so a typed dead time is refused.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

Poly = np.ndarray
Rational = tuple[Poly, Poly]


class ExpressionError(ValueError):
    """A controller expression that cannot be used; one line that says where."""


def controller_tf(text: str, option: str = "--k1") -> Rational:
    """A proper transfer function of s from text, e.g. ``5*(1+6.2*s)/s``: (numerator,
    denominator), highest power first, the denominator's leading coefficient 1."""
    from quadtank_tui.core.delaytf import ModelError
    from quadtank_tui.core.design.expr import ExprError, parse_model

    try:
        g = parse_model(text)
    except ExprError as exc:
        raise ExpressionError(f"{option} {text!r}: {exc.what} (column {exc.column})") from None
    except ModelError as exc:
        raise ExpressionError(f"{option} {text!r}: {exc}") from None
    if g.delay > 0.0:
        raise ExpressionError(f"{option} {text!r}: a dead time exp(-{g.delay:g}*s) cannot be used: "
                              "ICAD needs the controller as num/den in s")
    return _monic(np.array(g.num, dtype=float), np.array(g.den, dtype=float))


def _monic(num: Poly, den: Poly) -> Rational:
    """The same function with a denominator whose leading coefficient is 1."""
    num, den = np.asarray(num, dtype=float), np.trim_zeros(np.asarray(den, dtype=float), "f")
    return num / den[0], den / den[0]


def controller_from_par(element: object, family: str, scale: float) -> Rational:
    """A controller element of the loop (normalized u per normalized e) as volts per
    volt: PID K (b-free form) K (1 + 1/(Ti s) + Td s / (1 + Td s / N)) (the design's
    PID.feedback_tf), or the General controller's polynomials; times `scale` = pump
    full scale / 10 V."""
    from quadtank_tui.core.design.pid_tuning import PIDTuning
    from quadtank_tui.core.parameters import ControllerElement

    assert isinstance(element, ControllerElement)
    if family == "General":
        g = element.general
        num = np.array(g.s[: g.degree + 1], dtype=float)
        den = np.array((1.0, *g.r[: g.degree]), dtype=float)
        return _monic(num * scale, den)
    p = element.pid
    num, den = PIDTuning(p.K, p.Ti if p.integral else math.inf, p.Td if p.derivative else 0.0, p.N).feedback_tf()
    return _monic(num * scale, den)


def coefficients(k: Rational) -> dict[str, list[float]]:
    """JSON form: {"num": [...], "den": [...]}, highest power first."""
    return {"num": [float(x) for x in k[0]], "den": [float(x) for x in k[1]]}


def show(k: Rational) -> str:
    """(31s + 5)/(1s) style, 4 significant digits."""
    def poly(c: Sequence[float] | np.ndarray) -> str:
        n = len(c) - 1
        text = ""
        for i, x in enumerate(c):
            if x != 0:
                power = "" if n - i == 0 else ("s" if n - i == 1 else f"s^{n - i}")
                sign = ("-" if x < 0 else "") if not text else (" - " if x < 0 else " + ")
                text += f"{sign}{abs(x):.4g}{power}"
        return text or "0"

    return f"({poly(k[0])})/({poly(k[1])})"
