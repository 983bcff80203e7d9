"""The STATE FEEDBACK section of a `.par` file: what the user chooses.

Ts           settling time, s (the Bessel poles are Table 8's divided by it)
Poles        s-plane poles (rad/s) to use before the Bessel ones: "zeros" (the
             plant's slow zeros, Desautel 4.1.2; the default), "none", or numbers,
             e.g. "-0.0575 -0.0225" (his QTP) or "-0.2+0.1j -0.2-0.1j"
L3           anti-windup gain as a multiple of L2^-1 (1: the integral part of u is
             pulled exactly back to the limit; tracking.py)
Smart        1: the smart integrator; 0: the plain one (for comparison, 3.3)
LevelMargin  cm below the top of an upper tank where the level limit acts (3.2.2)
Level1/2     the lower-tank levels, cm, the design linearizes at (the upper levels
             and the pump voltages u_e follow from the steady state)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from quadtank_tui.core.controllers.statefb.bessel import BESSEL_POLES
from quadtank_tui.core.ranges import ParameterError, check_range

#: Largest design-model order Table 8 covers (4 states + 2 integrators on the QTP).
MAX_ORDER = max(BESSEL_POLES)


ZEROS = "zeros"


def parse_poles(text: str, key: str = "Poles") -> tuple[complex, ...]:
    """Poles from text ("none", "zeros" (none given here) or numbers like -0.1,
    -0.2+0.1j, -0.2-0.1i)."""
    words = text.replace(",", " ").split()
    if not words or (len(words) == 1 and words[0].lower() in ("none", "-", ZEROS)):
        return ()
    poles = []
    for w in words:
        try:
            p = complex(w.replace("i", "j"))
        except ValueError:
            raise ParameterError(key, f"{w!r} is not a pole (write -0.1 or -0.2+0.1j)") from None
        if not (math.isfinite(p.real) and math.isfinite(p.imag)) or p.real >= 0:
            raise ParameterError(key, f"pole {w} must have a negative real part")
        poles.append(p)
    if len(poles) > MAX_ORDER:
        raise ParameterError(key, f"at most {MAX_ORDER} poles, got {len(poles)}")
    rest = [p for p in poles if p.imag != 0]
    while rest:
        p = rest.pop()
        if p.conjugate() not in rest:
            raise ParameterError(key, f"pole {p} needs its conjugate {p.conjugate()}")
        rest.remove(p.conjugate())
    return tuple(poles)


def format_poles(poles: tuple[complex, ...]) -> str:
    """The text :func:`parse_poles` reads back ("none" for no poles)."""
    if not poles:
        return "none"
    return " ".join(f"{p.real:g}" if p.imag == 0 else f"{p.real:g}{p.imag:+g}j" for p in poles)


@dataclass(frozen=True)
class StateFeedbackParams:
    """The STATE FEEDBACK section (see the module docstring); validated here."""

    settling_time: float = 60.0
    poles: str = ZEROS
    l3: float = 1.0
    smart: bool = True
    level_margin: float = 2.0
    level1: float = 12.4
    level2: float = 12.7

    def __post_init__(self) -> None:
        check_range("Ts", self.settling_time, 1.0, 1e4)
        if not isinstance(self.poles, str):
            raise ParameterError("Poles", f"must be text, got {self.poles!r}")
        parse_poles(self.poles)
        check_range("L3", self.l3, 0.0, 100.0)
        check_range("LevelMargin", self.level_margin, 0.0, 50.0, lo_open=True)
        check_range("Level1", self.level1, 0.0, 200.0, lo_open=True)
        check_range("Level2", self.level2, 0.0, 200.0, lo_open=True)

    def pole_values(self) -> tuple[complex, ...]:
        return parse_poles(self.poles)

    @property
    def use_zeros(self) -> bool:
        """Whether the plant's slow zeros are chosen as poles ("zeros")."""
        return self.poles.strip().lower() == ZEROS
