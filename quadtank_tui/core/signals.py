"""Wave generators for the two input/reference channels (Nunes 1998, 5.3-5.4).

value = mean + amplitude * w, w in [-1, 1].  Square: the sign of a sine of the
given period.  Sine.  PRBS: a maximal-length sequence whose level is held for
`period` samples between possible changes (the original's meaning of Period for
PRBS), seeded so runs are reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from quadtank_tui.core.validation import ParameterError, check_number, check_range


class Wave(str, Enum):
    """Wave types, spelled as in the `.par` file's `Wave` key."""

    SQUARE = "Square"
    SINE = "Sine"
    PRBS = "PRBS"


@dataclass(frozen=True)
class WaveParams:
    """One generator's settings, normalized units (fraction of 10 V).

    period : seconds for Square/Sine; samples between possible changes for PRBS.
    on : False gives a constant at the mean.
    seed : PRBS register seed (any non-zero 31-bit value; 0 is mapped to 1).
    """

    wave: Wave = Wave.SQUARE
    mean: float = 0.30
    amplitude: float = 0.0
    period: float = 60.0
    on: bool = False
    seed: int = 1

    def __post_init__(self) -> None:
        if not isinstance(self.wave, Wave):
            try:
                object.__setattr__(self, "wave", Wave(self.wave))
            except ValueError:
                raise ParameterError("Wave", f"must be Square, Sine or PRBS, got {self.wave!r}") from None
        check_range("Mean", self.mean, -1.0, 2.0)
        check_range("Amplitude", self.amplitude, 0.0, 1.0)
        check_range("Period", self.period, 0.0, 1e6, lo_open=True)
        if not isinstance(self.on, bool):
            raise ParameterError("On", f"must be on/off, got {self.on!r}")
        check_number("Seed", self.seed)
        if int(self.seed) != self.seed or not 0 <= self.seed < 2**31:
            raise ParameterError("Seed", f"must be an integer in [0, 2^31), got {self.seed!r}")
