"""The PI/PID controller that design produces and evaluation closes the loop with.

Andersson's form (003_... section 3.1), with the derivative filtered and acting on
the measurement, as his PID_opt rows were evaluated (control.md)::

    u = Kc (b r - y) + Kc/Ti * integral(r - y) - Kc Td s / (1 + s Td/N) y

Gains are in controller units per process-output unit; Ti, Td in seconds.  A
negative Kc controls a process with a negative gain (his processes 2 and 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from quadtank_tui.core.delaytf import DelayTF

#: derivative filter: Td s / (1 + s Td / N), Andersson's evaluation convention.
DERIVATIVE_FILTER_N = 10.0


class DesignError(ValueError):
    """A design that cannot be made: the message says which model or spec is wrong."""


@dataclass(frozen=True)
class PIDTuning:
    """Kc, Ti (s), Td (s, 0 for PI); `N` divides Td in the derivative filter."""

    Kc: float
    Ti: float
    Td: float = 0.0
    N: float = DERIVATIVE_FILTER_N
    b: float = 1.0

    def __post_init__(self) -> None:
        for name in ("Kc", "Ti", "Td", "N", "b"):  # plain floats (numpy scalars print badly)
            object.__setattr__(self, name, float(getattr(self, name)))

    def rounded(self, digits: int = 4) -> PIDTuning:
        """Kc, Ti, Td to `digits` significant figures: what is applied and saved."""
        def r(x: float) -> float:
            return float(f"{x:.{digits}g}") if math.isfinite(x) else x
        return PIDTuning(r(self.Kc), r(self.Ti), r(self.Td), self.N, self.b)

    @property
    def ki(self) -> float:
        """Integral gain Kc/Ti: load-disturbance IE = step / ki."""
        return self.Kc / self.Ti if math.isfinite(self.Ti) else 0.0

    @property
    def kind(self) -> str:
        return "PID" if self.Td > 0.0 else "PI"

    def feedback_tf(self) -> tuple[np.ndarray, np.ndarray]:
        """Gy(s) = Kc (1 + 1/(Ti s) + Td s/(1 + s Td/N)) as (num, den), descending s."""
        integral = np.array([self.Ti, 0.0]) if math.isfinite(self.Ti) else np.array([1.0])
        i_num = np.array([self.Ti, 1.0]) if math.isfinite(self.Ti) else np.array([1.0])
        if self.Td > 0.0:
            filt = np.array([self.Td / self.N, 1.0])
            num = np.polyadd(np.polymul(i_num, filt), np.polymul(integral, [self.Td, 0.0]))
            den = np.polymul(integral, filt)
        else:
            num, den = i_num, integral
        return self.Kc * num, den

    def loop(self, g: DelayTF) -> DelayTF:
        """The loop transfer function L = Gy G (delay kept exact)."""
        num, den = self.feedback_tf()
        return DelayTF(tuple(np.polymul(num, g.num)), tuple(np.polymul(den, g.den)), g.delay)

    def freqresp(self, w: npt.ArrayLike) -> np.ndarray:
        """Gy(i w), one value per frequency (a P controller too: Ti = inf)."""
        s = 1j * np.asarray(w, dtype=float)
        c = 1.0 + (1.0 / (self.Ti * s) if math.isfinite(self.Ti) else np.zeros_like(s))
        if self.Td > 0.0:
            c = c + self.Td * s / (1.0 + s * self.Td / self.N)
        return self.Kc * c

    def describe(self) -> str:
        text = f"Kc={self.Kc:.4g}, Ti={self.Ti:.4g}"
        return text + (f", Td={self.Td:.4g}" if self.Td > 0.0 else "")
