"""A SISO rational transfer function with a dead time: the model type shared by
identification (what a fit produces) and PI/PID design (what a design consumes).

    G(s) = num(s) / den(s) * exp(-delay s)

Coefficients are in descending powers of s (numpy/python-control order); time in
seconds, so frequencies are rad/s.  The delay is kept exact (never a Pade
approximation) because Ms-constrained design and the margins are computed in the
frequency domain, where exp(-i w L) costs nothing.

Example
-------
>>> g = DelayTF((1.6592,), (1.07**3, 3 * 1.07**2, 3 * 1.07, 1.0), 2.4)
>>> round(g.static_gain, 4), g.integrators
(1.6592, 0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import overload

import numpy as np


class ModelError(ValueError):
    """A model that cannot describe a process (bad coefficients, negative delay)."""


def _trim(coeffs: tuple[float, ...]) -> tuple[float, ...]:
    """Drop leading zeros so that the degree is the true degree."""
    i = 0
    while i < len(coeffs) - 1 and coeffs[i] == 0.0:
        i += 1
    return coeffs[i:]


@dataclass(frozen=True)
class DelayTF:
    """num(s)/den(s) e^(-delay s); coefficients descending in s, delay in s."""

    num: tuple[float, ...]
    den: tuple[float, ...]
    delay: float = 0.0

    def __post_init__(self) -> None:
        num = _trim(tuple(float(c) for c in self.num))
        den = _trim(tuple(float(c) for c in self.den))
        if not num or not den:
            raise ModelError("numerator and denominator need at least one coefficient")
        if not all(math.isfinite(c) for c in num + den):
            raise ModelError("coefficients must be finite numbers")
        if den == (0.0,):
            raise ModelError("the denominator is zero")
        if len(num) > len(den):
            raise ModelError(
                f"improper model: numerator degree {len(num) - 1} > denominator degree {len(den) - 1}"
            )
        delay = float(self.delay)
        if not math.isfinite(delay) or delay < 0.0:
            raise ModelError(f"the delay must be a finite number >= 0 s, got {self.delay!r}")
        object.__setattr__(self, "num", num)
        object.__setattr__(self, "den", den)
        object.__setattr__(self, "delay", delay)

    @property
    def integrators(self) -> int:
        """How many poles at s = 0 (an integrating process has 1)."""
        n = 0
        den = list(self.den)
        while len(den) > 1 and den[-1] == 0.0:
            den.pop()
            n += 1
        return n

    @property
    def static_gain(self) -> float:
        """G(0) for a self-regulating model; for an integrating one, the velocity
        gain Kv = lim s->0 s^n G(s) (the K of K/s e^-sL)."""
        n = self.integrators
        den = self.den[: len(self.den) - n] if n else self.den
        return self.num[-1] / den[-1] if den[-1] != 0.0 else math.inf

    @overload
    def freqresp(self, w: float) -> complex: ...
    @overload
    def freqresp(self, w: np.ndarray) -> np.ndarray: ...

    def freqresp(self, w: np.ndarray | float) -> np.ndarray | complex:
        """G(i w), w in rad/s, delay exact: a number for a number, an array for an array."""
        s = 1j * np.asarray(w, dtype=float)
        return np.polyval(self.num, s) / np.polyval(self.den, s) * np.exp(-s * self.delay)

    def poles(self) -> np.ndarray:
        """Roots of den (1/s)."""
        return np.roots(self.den) if len(self.den) > 1 else np.zeros(0)

    def zeros(self) -> np.ndarray:
        """Roots of num (1/s); the delay adds none."""
        return np.roots(self.num) if len(self.num) > 1 else np.zeros(0)

    def __str__(self) -> str:
        def poly(c: tuple[float, ...]) -> str:
            deg = len(c) - 1
            terms = []
            for i, a in enumerate(c):
                p = deg - i
                if a == 0.0:
                    continue
                s = "" if p == 0 else ("s" if p == 1 else f"s^{p}")
                terms.append(f"{a:.6g}{'*' if s else ''}{s}")
            return " + ".join(terms) or "0"

        text = f"({poly(self.num)})/({poly(self.den)})"
        return text + (f"*exp(-{self.delay:.6g}*s)" if self.delay else "")
