"""A model written the way a control engineer reads it, short enough for a box.

    2.61*exp(-0.041*s)/(62.14*s+1)          gain, dead time, time constants
    1.659*exp(-2.4*s)/(1.07*s+1)^3          a repeated lag once, with its power
    -0.00651*exp(-2*s)/s                    an integrator as 1/s

The coefficient form a DelayTF prints (`(1.659)/(1.22504*s^3 + 3.4347*s^2 + ...)*exp(-2.4*s)`)
hides the time constants and, in a narrow box, the dead time at its end (`exp(-0.`).
Here the gain comes first, then the dead time, then one factor per zero and pole:
(T s + 1) for a real one, (a s^2 + b s + 1) for a complex pair, rounded to
`digits` significant digits.  The text reads back with core.design.expr.parse_model
(to those digits); the screen keeps the exact model until the text is edited.
"""

from __future__ import annotations

import math

import numpy as np

from quadtank_tui.core.delaytf import DelayTF

#: Roots within this share of their size are one (a repeated root comes out of
#: numpy.roots split by about eps^(1/k)); below ZERO (1/s) a root is at s = 0.
SAME, ZERO = 1e-3, 1e-12


def num(x: float, digits: int) -> str:
    """`x` to `digits` significant digits, no trailing zeros (parse_model reads it)."""
    return f"{x:.{digits}g}"


def _times_s(c: float, power: str, digits: int) -> str:
    """c*s^power, with "s" alone for c = 1."""
    text = num(c, digits)
    return power if text == "1" else f"{text}*{power}"


def _clusters(roots: np.ndarray) -> list[tuple[complex, int]]:
    """The roots grouped: (mean, multiplicity), the s = 0 roots left out."""
    groups: list[list[complex]] = []
    for r in roots:
        if abs(r) <= ZERO:
            continue
        for group in groups:
            mean = sum(group) / len(group)
            if abs(r - mean) <= SAME * abs(mean):
                group.append(complex(r))
                break
        else:
            groups.append([complex(r)])
    return [(sum(g) / len(g), len(g)) for g in groups]


def _factors(roots: np.ndarray, digits: int) -> tuple[int, list[str]]:
    """(roots at s = 0, the others as "(T*s+1)" or "(a*s^2+b*s+1)", a repeated one ^k),
    the slowest first."""
    at_zero = int(np.sum(np.abs(roots) <= ZERO))
    texts = []
    for r, k in sorted(_clusters(roots), key=lambda c: abs(c[0])):
        if abs(r.imag) <= SAME * abs(r):
            text = f"({_times_s(-1.0 / r.real, 's', digits)}+1)"
        elif r.imag > 0.0:  # (s - r)(s - r*) / |r|^2; its conjugate is the same factor
            m2 = abs(r) ** 2
            text = f"({_times_s(1.0 / m2, 's^2', digits)}+{_times_s(-2.0 * r.real / m2, 's', digits)}+1)"
        else:
            continue
        texts.append(text.replace("+-", "-") + (f"^{k}" if k > 1 else ""))
    return at_zero, texts


def _gain(g: DelayTF, zn: int, zd: int) -> float:
    """The gain K of K s^(zn - zd) prod(T s + 1)...: the ratio of the lowest
    non-zero coefficients (the static gain, or an integrator's velocity gain)."""
    n, d = g.num[: len(g.num) - zn], g.den[: len(g.den) - zd]
    return n[-1] / d[-1]


def model_text(g: DelayTF, digits: int = 4) -> str:
    """`g` in gain / dead-time / time-constant form (see the module's docstring)."""
    zn, top = _factors(g.zeros(), digits)
    zd, bottom = _factors(g.poles(), digits)
    try:
        k = _gain(g, zn, zd)
    except (IndexError, ZeroDivisionError):
        return str(g)
    if not math.isfinite(k) or k == 0.0:
        return str(g)
    power = zn - zd  # s^power multiplies the rest
    if power > 0:
        top.insert(0, "s" if power == 1 else f"s^{power}")
    elif power < 0:
        bottom.insert(0, "s" if power == -1 else f"s^{-power}")
    text = num(k, digits)
    if g.delay:
        text += f"*exp(-{num(g.delay, digits)}*s)"
    if top:
        text += "*" + "*".join(top)
    if bottom:
        text += "/" + (bottom[0] if len(bottom) == 1 else "(" + "*".join(bottom) + ")")
    return text
