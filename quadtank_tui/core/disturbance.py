"""The IST Lisbon rig's two disturbance pumps as an inflow (pure: no I/O).

The rig (Pedroso and Batista, J. Process Control 118, 2022) has, beside its two
actuation pumps, two disturbance pumps the host drives with the last two bytes of
its pump frame (8-bit PWM, d = PWM / 255).  Where they pour and how much comes from
the rig's own simulator, github.com/decenter2021/quadruple-tank-setup at commit
6988f8cfc8a82e0d35ede605cbc56994f1a7a837,
simulink/quadruple-simulink-block/quadrupleLoadParameters.m and quadrupleSimObj.m
(xdotContinuous):

- ``cte.d_tanks = [1;2]``: disturbance pump i pours into tank i, the two lower tanks
  (the rig numbers its tanks as this program does: 1, 2 below, 3 above 1, 4 above 2);
- ``q_d = k(1) c(1,1) d_scale (d - c(3,1)) / (d - c(2,1))`` cm^3/s for d above
  max(c(3,1), c(2,1)), else nothing, with ``d_scale = 0.05`` and actuation pump 1's
  identified c1, c2, c3, k (identification/pump.mat): 5.9 cm^3/s at full PWM,
  about a third of a pump at 6 V.

The README says the disturbance pumps' own identification depends on the height of
their outlet; the rig's simulator uses the law above, and so do ours (the Simul
disturbance, engine/sim.py, and the virtual device, daq/ist/device.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: The rig's simulator's disturbance scale (quadrupleLoadParameters.m, cte.d_scale).
D_SCALE = 0.05
#: 8-bit PWM of a disturbance pump (analogWrite).
PWM_MAX = 255


@dataclass(frozen=True)
class DisturbancePumps:
    """The law q = k c1 scale (d - c3) / (d - c2) cm^3/s at duty d in [0, 1], pump i
    into tank `tanks[i]` (1-based)."""

    c1: float
    c2: float
    c3: float
    k: float
    scale: float = D_SCALE
    tanks: tuple[int, int] = (1, 2)

    def flow(self, d: float) -> float:
        """cm^3/s of one disturbance pump at duty `d` (0 at or below its threshold)."""
        if not (math.isfinite(d) and 0.0 <= d <= 1.0):
            raise ValueError(f"a disturbance pump's duty must be in 0..1, got {d!r}")
        if d <= max(self.c3, self.c2):
            return 0.0
        return self.k * self.c1 * self.scale * (d - self.c3) / (d - self.c2)

    def inflow(self, duties: tuple[float, float], tanks: int = 4) -> tuple[float, ...]:
        """cm^3/s into each of `tanks` tanks with the two pumps at `duties`."""
        out = [0.0] * tanks
        for tank, d in zip(self.tanks, duties):
            out[tank - 1] += self.flow(d)
        return tuple(out)


#: The published rig's (pump 1's c1, c2, c3, k of identification/pump.mat, as
#: daq/ist/protocol.py has them).
IST = DisturbancePumps(c1=39.010223117576864, c2=-0.0012401118595907013, c3=0.03385649940174739,
                       k=3.1368993540698913)


def quantized(fraction: float) -> float:
    """A fraction of full PWM as the 8-bit PWM the rig gets makes it (d = round(255 f) / 255)."""
    return round(fraction * PWM_MAX) / PWM_MAX


def updated(duties: tuple[float, float], d1: float | None, d2: float | None) -> tuple[float, float]:
    """`duties` with d1, d2 set (None: left as it is), each a fraction of full PWM
    quantized to the 8 bits; ValueError naming one outside 0..1 (nothing set)."""
    out = list(duties)
    for i, (name, d) in enumerate((("d1", d1), ("d2", d2))):
        if d is None:
            continue
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not 0.0 <= d <= 1.0:
            raise ValueError(f"{name} must be in 0..1 (a fraction of full PWM), got {d}")
        out[i] = quantized(float(d))
    return out[0], out[1]
