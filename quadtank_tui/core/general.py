"""General transfer-function element (Nunes 1998, 5.5).

    U(s) = (s0 s^n + s1 s^(n-1) + ... + sn) / (s^n + r1 s^(n-1) + ... + rn) E(s),  n = 0..4
"""

from __future__ import annotations

from dataclasses import dataclass

from quadtank_tui.core.validation import ParameterError, check_number

MAX_DEGREE = 4


@dataclass(frozen=True)
class GeneralParams:
    """Degree n and the coefficients; s holds s0..s4, r holds r1..r4 (only the
    first n + 1 of s and n of r are used)."""

    degree: int = 0
    s: tuple[float, float, float, float, float] = (1.0, 0.0, 0.0, 0.0, 0.0)
    r: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if isinstance(self.degree, bool) or self.degree not in range(MAX_DEGREE + 1):
            raise ParameterError("Degree", f"must be an integer 0..{MAX_DEGREE}, got {self.degree!r}")
        if len(self.s) != 5 or len(self.r) != 4:
            raise ParameterError("s0", "five numerator (s0..s4) and four denominator (r1..r4) coefficients")
        for i, x in enumerate(self.s):
            check_number(f"s{i}", x)
        for i, x in enumerate(self.r):
            check_number(f"r{i + 1}", x)

    @property
    def numerator(self) -> tuple[float, ...]:
        """s0..sn, highest power first."""
        return tuple(self.s[: self.degree + 1])

    @property
    def denominator(self) -> tuple[float, ...]:
        """1, r1..rn, highest power first (monic)."""
        return (1.0, *self.r[: self.degree])
