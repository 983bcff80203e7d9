"""Parse a typed model such as ``1.6592*exp(-2.4*s)/(1.07*s+1)^3`` into a DelayTF.

A small recursive-descent parser (never ``eval``): numbers, the variable ``s``,
``+ - * /``, parentheses, integer powers (``^`` or ``**``, e.g. ``(s+1)^3``,
``s^-1``), implicit products (``2s``, ``(s+1)(2s+1)``) and delay factors
``exp(-L*s)`` with L >= 0.  A delay may only multiply or divide the whole model
(``exp`` inside a sum is not a dead time), and it must come out >= 0.

Errors are :class:`ExprError`, whose message shows the expression with a caret
under the offending character, so a user sees where to fix it.

The work is bounded whatever is typed or pasted: at most MAX_LENGTH characters,
parentheses nested at most MAX_DEPTH deep (the parser recurses), and polynomials
of at most MAX_ORDER (each product costs the product of the orders, so an
expression of thousands of factors would otherwise take seconds).

Example
-------
>>> g = parse_model("-0.00652*exp(-2*s)/(s*(49.33*s+1))")
>>> g.integrators, g.delay, round(g.static_gain, 5)
(1, 2.0, -0.00652)
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from quadtank_tui.core.delaytf import DelayTF, ModelError

_TOKEN = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>[A-Za-z_]\w*)"
    r"|(?P<op>\*\*|[-+*/^()]))"
)
MAX_POWER = 20
#: Characters of an expression (a process model is a few dozen).
MAX_LENGTH = 1000
#: Parentheses (and exp( ) nested inside each other.
MAX_DEPTH = 50
#: The order of the numerator or denominator polynomial, at any step of the parse.
MAX_ORDER = 60


class ExprError(ModelError):
    """A model expression that cannot be read; `column` is 1-based."""

    def __init__(self, text: str, pos: int, what: str) -> None:
        self.text, self.column, self.what = text, pos + 1, what
        super().__init__(
            f"bad model expression at column {pos + 1}: {what}\n  {text}\n  {' ' * pos}^"
        )


@dataclass(frozen=True)
class _Tok:
    kind: str  # "num", "name", "op", "end"
    text: str
    pos: int


_BLANK_TO_END = re.compile(r"\s*\Z")


def _tokenize(text: str) -> list[_Tok]:
    if len(text) > MAX_LENGTH:
        raise ExprError(text[:60] + "...", 60, f"the expression has {len(text)} characters; "
                        f"a model has at most {MAX_LENGTH}")
    toks: list[_Tok] = []
    pos = 0
    while pos < len(text):
        if _BLANK_TO_END.match(text, pos):
            break
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            bad = pos + len(text[pos:]) - len(text[pos:].lstrip())
            raise ExprError(text, bad, f"unexpected character {text[bad]!r}")
        kind = m.lastgroup or "op"
        start = m.start(kind)
        toks.append(_Tok(kind, m.group(kind), start))
        pos = m.end()
    toks.append(_Tok("end", "", len(text)))
    return toks


def _poly(c: np.ndarray) -> np.ndarray:
    """Polynomial coefficients, highest power first, without leading zeros ([0.]
    for zero).  Plain arrays and np.convolve: np.poly1d costs about 0.4 ms an
    operation, which made a 900-character product take half a second."""
    nz = np.flatnonzero(c)
    return c[nz[0]:] if nz.size else np.zeros(1)


@dataclass(frozen=True)
class _Rat:
    """num/den in s (coefficient arrays, highest power first) times exp(-delay s);
    `delayed` once an exp appeared."""

    num: np.ndarray
    den: np.ndarray
    delay: float = 0.0
    delayed: bool = False

    @property
    def order(self) -> int:
        return max(len(self.num), len(self.den)) - 1

    def mul(self, o: _Rat) -> _Rat:
        return _Rat(_poly(np.convolve(self.num, o.num)), _poly(np.convolve(self.den, o.den)),
                    self.delay + o.delay, self.delayed or o.delayed)

    def div(self, o: _Rat) -> _Rat:
        return _Rat(_poly(np.convolve(self.num, o.den)), _poly(np.convolve(self.den, o.num)),
                    self.delay - o.delay, self.delayed or o.delayed)

    def add(self, o: _Rat, sign: float) -> _Rat:
        num = np.polyadd(np.convolve(self.num, o.den), sign * np.convolve(o.num, self.den))
        return _Rat(_poly(num), _poly(np.convolve(self.den, o.den)))

    def is_zero(self) -> bool:
        return not np.any(self.num)


def _const(x: float) -> _Rat:
    return _Rat(np.array([x]), np.ones(1))


class _Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.toks = _tokenize(text)
        self.i = 0
        self.depth = 0

    def nested(self, opened: _Tok) -> None:
        """One level deeper (a '(' or an exp( ); ExprError beyond MAX_DEPTH."""
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.fail(f"parentheses nested more than {MAX_DEPTH} deep", opened)

    def bounded(self, value: _Rat, at: _Tok) -> _Rat:
        """`value`, or ExprError if its order passed MAX_ORDER."""
        if value.order > MAX_ORDER:
            raise self.fail(f"the model's order grows above {MAX_ORDER} here: not a process model", at)
        return value

    # -- helpers
    @property
    def tok(self) -> _Tok:
        return self.toks[self.i]

    def fail(self, what: str, tok: _Tok | None = None) -> ExprError:
        return ExprError(self.text, (tok or self.tok).pos, what)

    def take(self, op: str) -> bool:
        if self.tok.kind == "op" and self.tok.text == op:
            self.i += 1
            return True
        return False

    def expect(self, op: str, opened: _Tok | None = None) -> None:
        if not self.take(op):
            found = "the end" if self.tok.kind == "end" else repr(self.tok.text)
            extra = f" to close the '(' at column {opened.pos + 1}" if opened else ""
            raise self.fail(f"expected {op!r}{extra}, found {found}")

    # -- grammar
    def parse(self) -> _Rat:
        if self.tok.kind == "end":
            raise self.fail("the expression is empty")
        value = self.sum()
        if self.tok.kind != "end":
            raise self.fail(f"unexpected {self.tok.text!r}")
        return value

    def sum(self) -> _Rat:
        value = self.product()
        while self.tok.kind == "op" and self.tok.text in "+-":
            op = self.tok
            self.i += 1
            rhs = self.product()
            if value.delayed or rhs.delayed:
                raise self.fail("a delay exp(-L*s) may only multiply the whole model, not a term of a sum", op)
            value = self.bounded(value.add(rhs, 1.0 if op.text == "+" else -1.0), op)
        return value

    def starts_factor(self) -> bool:
        t = self.tok
        return t.kind in ("num", "name") or (t.kind == "op" and t.text == "(")

    def product(self) -> _Rat:
        value = self.unary()
        while True:
            op = self.tok
            if op.kind == "op" and op.text in ("*", "/"):
                self.i += 1
                rhs = self.unary()
                if op.text == "*":
                    value = self.bounded(value.mul(rhs), op)
                else:
                    if rhs.is_zero():
                        raise self.fail("division by zero", op)
                    value = self.bounded(value.div(rhs), op)
            elif self.starts_factor():  # implicit product: 2s, (s+1)(s+2)
                value = self.bounded(value.mul(self.unary()), op)
            else:
                return value

    def unary(self) -> _Rat:
        negative = False
        while self.tok.kind == "op" and self.tok.text in "+-":  # a loop: "- - -s" does not recurse
            negative ^= self.tok.text == "-"
            self.i += 1
        v = self.power()
        return _Rat(-v.num, v.den, v.delay, v.delayed) if negative else v

    def power(self) -> _Rat:
        base = self.atom()
        if self.tok.kind == "op" and self.tok.text in ("^", "**"):
            self.i += 1
            sign = -1 if self.take("-") else 1
            t = self.tok
            if t.kind != "num" or not re.fullmatch(r"\d+", t.text):
                raise self.fail("a power must be an integer, e.g. (s+1)^3")
            self.i += 1
            n = int(t.text)
            if n > MAX_POWER:
                raise self.fail(f"a power above {MAX_POWER} is not a process model", t)
            if sign < 0 and base.is_zero():
                raise self.fail("division by zero", t)
            if n * base.order > MAX_ORDER:
                raise self.fail(f"the model's order grows above {MAX_ORDER} here: not a process model", t)
            out = _const(1.0)
            for _ in range(n):
                out = out.mul(base) if sign > 0 else out.div(base)
            return _Rat(out.num, out.den, out.delay, base.delayed)
        return base

    def atom(self) -> _Rat:
        t = self.tok
        if t.kind == "num":
            self.i += 1
            x = float(t.text)
            if not math.isfinite(x):
                raise self.fail("number out of range", t)
            return _const(x)
        if t.kind == "name":
            self.i += 1
            if t.text == "s":
                return _Rat(np.array([1.0, 0.0]), np.ones(1))
            if t.text == "exp":
                return self.delay_factor(t)
            raise self.fail(f"unknown name {t.text!r}: only s and exp(-L*s) may appear", t)
        if self.take("("):
            self.nested(t)
            value = self.sum()
            self.expect(")", t)
            self.depth -= 1
            return value
        found = "the end" if t.kind == "end" else repr(t.text)
        raise self.fail(f"expected a number, s, exp(...) or '(', found {found}")

    def delay_factor(self, name: _Tok) -> _Rat:
        opened = self.tok
        self.expect("(")
        self.nested(opened)
        arg = self.sum()
        self.expect(")", opened)
        self.depth -= 1
        num = np.trim_zeros(arg.num, "f")
        den = np.trim_zeros(arg.den, "f")
        linear = (not arg.delayed and len(den) == 1 and len(num) <= 2
                  and (len(num) < 2 or num[-1] == 0.0))
        if not linear:
            raise self.fail("the argument of exp must be -L*s with a number L >= 0", opened)
        slope = float(num[0] / den[0]) if len(num) == 2 else 0.0
        return _Rat(np.ones(1), np.ones(1), -slope, True)


def parse_model(text: str) -> DelayTF:
    """The DelayTF of `text`; ExprError (a ModelError) points at what is wrong."""
    value = _Parser(text).parse()
    if value.delay < 0.0:
        raise ExprError(text, 0, f"the total delay is {value.delay:g} s: a dead time must be >= 0")
    num = np.trim_zeros(value.num, "f")
    den = np.trim_zeros(value.den, "f")
    if len(num) == 0:
        raise ExprError(text, 0, "the model is identically zero")
    try:
        return DelayTF(tuple(float(c) for c in num), tuple(float(c) for c in den), value.delay)
    except ModelError as exc:
        raise ExprError(text, 0, str(exc)) from None
