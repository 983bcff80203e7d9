"""PID element (Astrom & Hagglund; Nunes 1998, 5.5).

    U = K [ b R - Y + 1/(s Ti) (R - Y) + s Td / (1 + s Td / N) (a R - Y) ]
"""

from __future__ import annotations

from dataclasses import dataclass

from quadtank_tui.core.validation import ParameterError, check_range


@dataclass(frozen=True)
class PIDParams:
    """One PID element's settings (keys as in the `.par` CONTROLLER sections).

    K : gain, normalized input per normalized error (may be negative, as at P+)
    Ti : integral time, s (> 0)
    Td : derivative time, s (>= 0)
    Tr : anti-windup tracking (reset) time, s (> 0)
    N : maximum derivative gain (> 0)
    a, b : setpoint weights of the D and P parts, [0, 1]
    integral, derivative : the I and D parts switched on
    """

    K: float = 1.0
    Ti: float = 30.0
    Td: float = 0.0
    Tr: float = 1.0
    N: float = 10.0
    a: float = 0.0
    b: float = 1.0
    integral: bool = True
    derivative: bool = False

    def __post_init__(self) -> None:
        check_range("K", self.K, -1e3, 1e3)
        check_range("Ti", self.Ti, 0.0, 1e6, lo_open=True)
        check_range("Td", self.Td, 0.0, 1e6)
        check_range("Tr", self.Tr, 0.0, 1e6, lo_open=True)
        check_range("N", self.N, 0.0, 1e3, lo_open=True)
        check_range("a", self.a, 0.0, 1.0)
        check_range("b", self.b, 0.0, 1.0)
        for name in ("integral", "derivative"):
            if not isinstance(getattr(self, name), bool):
                raise ParameterError("I" if name == "integral" else "D", "must be 0 or 1")
