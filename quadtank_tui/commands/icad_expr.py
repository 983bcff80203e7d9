"""Controller expressions for `quadtank icad`: a minimal reader of transfer functions in s.

Numbers, s, + - * / ^ with a whole exponent, brackets, implicit products such as
``5(1+6.2s)/s``.  Deliberately minimal: the `design` work brings the program's one
expression parser (core/design/expr.py), which should replace :func:`parse_tf` once
both are merged.
"""

from __future__ import annotations

import re
from typing import Sequence

import numpy as np

Poly = np.ndarray
Rational = tuple[Poly, Poly]

_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)|(s)|([-+*/^()]))")


class ExpressionError(ValueError):
    """A controller expression that cannot be read; says where."""


def _tokens(text: str) -> list[str]:
    out, pos = [], 0
    text = text.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise ExpressionError(f"{text!r}: cannot read {text[pos:].strip()[:12]!r} at character {pos + 1} "
                                  "(use numbers, s, + - * / ^ and brackets)")
        out.append(m.group(m.lastindex or 0))
        pos = m.end()
    return out


def _add(a: Rational, b: Rational, sign: float = 1.0) -> Rational:
    return np.polyadd(np.polymul(a[0], b[1]), sign * np.polymul(b[0], a[1])), np.polymul(a[1], b[1])


def _mul(a: Rational, b: Rational) -> Rational:
    return np.polymul(a[0], b[0]), np.polymul(a[1], b[1])


def _div(a: Rational, b: Rational, text: str) -> Rational:
    if not np.any(b[0]):
        raise ExpressionError(f"{text!r}: division by zero")
    return np.polymul(a[0], b[1]), np.polymul(a[1], b[0])


class _Reader:
    """Recursive descent: expr = term {(+|-) term}; term = unary {(*|/|implicit) unary};
    unary = (+|-) unary | power; power = atom [^ whole]; atom = number | s | (expr)."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.toks = _tokens(text)
        self.i = 0

    def peek(self) -> str | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self) -> str:
        tok = self.peek()
        if tok is None:
            raise ExpressionError(f"{self.text!r}: ends too early")
        self.i += 1
        return tok

    def expr(self) -> Rational:
        value = self.term()
        while self.peek() in ("+", "-"):
            sign = 1.0 if self.take() == "+" else -1.0
            value = _add(value, self.term(), sign)
        return value

    def term(self) -> Rational:
        value = self.unary()
        while True:
            tok = self.peek()
            if tok == "*":
                self.take()
                value = _mul(value, self.unary())
            elif tok == "/":
                self.take()
                value = _div(value, self.unary(), self.text)
            elif tok is not None and (tok in ("(", "s") or tok[0].isdigit() or tok[0] == "."):
                value = _mul(value, self.unary())  # implicit product: 5(1+s), 6.2s
            else:
                return value

    def unary(self) -> Rational:
        if self.peek() in ("+", "-"):
            sign = 1.0 if self.take() == "+" else -1.0
            num, den = self.unary()
            return sign * num, den
        return self.power()

    def power(self) -> Rational:
        base = self.atom()
        if self.peek() != "^":
            return base
        self.take()
        tok = self.take()
        if not tok.isdigit():
            raise ExpressionError(f"{self.text!r}: an exponent must be a whole number, got {tok!r}")
        num, den = np.array([1.0]), np.array([1.0])
        for _ in range(int(tok)):
            num, den = np.polymul(num, base[0]), np.polymul(den, base[1])
        return num, den

    def atom(self) -> Rational:
        tok = self.take()
        if tok == "s":
            return np.array([1.0, 0.0]), np.array([1.0])
        if tok == "(":
            value = self.expr()
            if self.take() != ")":
                raise ExpressionError(f"{self.text!r}: a bracket is not closed")
            return value
        if tok[0].isdigit() or tok[0] == ".":
            return np.array([float(tok)]), np.array([1.0])
        raise ExpressionError(f"{self.text!r}: unexpected {tok!r}")


def parse_tf(text: str) -> Rational:
    """A proper transfer function of s from text: (numerator, denominator), highest power first."""
    reader = _Reader(text)
    num, den = reader.expr()
    if reader.peek() is not None:
        raise ExpressionError(f"{text!r}: unexpected {reader.peek()!r} after a complete expression")
    num, den = np.trim_zeros(num, "f"), np.trim_zeros(den, "f")
    if den.size == 0:
        raise ExpressionError(f"{text!r}: the denominator is zero")
    if num.size == 0:
        num = np.array([0.0])
    if num.size > den.size:
        raise ExpressionError(f"{text!r}: improper (numerator of higher degree than the denominator); "
                              "filter a derivative, e.g. Td*s/(1+Td*s/10)")
    return _monic(num, den)


def _monic(num: Poly, den: Poly) -> Rational:
    """The same function with a denominator whose leading coefficient is 1."""
    num, den = np.asarray(num, dtype=float), np.trim_zeros(np.asarray(den, dtype=float), "f")
    return num / den[0], den / den[0]


def controller_from_par(element: object, family: str, scale: float) -> Rational:
    """A controller element of the loop (normalized u per normalized e) as volts per
    volt: PID K (b-free form) K (1 + 1/(Ti s) + Td s / (1 + Td s / N)), or the
    General controller's polynomials; times `scale` = pump full scale / 10 V."""
    from quadtank_tui.core.parameters import ControllerElement

    assert isinstance(element, ControllerElement)
    if family == "General":
        g = element.general
        num = np.array(g.s[: g.degree + 1], dtype=float)
        den = np.array((1.0, *g.r[: g.degree]), dtype=float)
        return _monic(num * scale, den)
    p = element.pid
    value: Rational = (np.array([1.0]), np.array([1.0]))
    if p.integral:
        value = _add(value, (np.array([1.0]), np.array([p.Ti, 0.0])))
    if p.derivative and p.Td > 0:
        value = _add(value, (np.array([p.Td, 0.0]), np.array([p.Td / p.N, 1.0])))
    return _monic(value[0] * p.K * scale, value[1])


def coefficients(k: Rational) -> dict[str, list[float]]:
    """JSON form: {"num": [...], "den": [...]}, highest power first."""
    return {"num": [float(x) for x in k[0]], "den": [float(x) for x in k[1]]}


def show(k: Rational) -> str:
    """(31s + 5)/(1s) style, 4 significant digits."""
    def poly(c: Sequence[float]) -> str:
        n = len(c) - 1
        text = ""
        for i, x in enumerate(c):
            if x != 0:
                power = "" if n - i == 0 else ("s" if n - i == 1 else f"s^{n - i}")
                sign = ("-" if x < 0 else "") if not text else (" - " if x < 0 else " + ")
                text += f"{sign}{abs(x):.4g}{power}"
        return text or "0"

    return f"({poly(k[0])})/({poly(k[1])})"
