"""The identified model next to the physical linearization at the experiment's
operating point: the levels in the first row of the log (normalized units in the
log, cm here), the upper tanks' from y3, y4 when logged, else the steady state of
the logged pump inputs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from quadtank_tui.core.analysis import Analysis, analyze
from quadtank_tui.core.identify.system import time_constants
from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError
from quadtank_tui.core.plants.johansson import SETTINGS, PlantParams, Setting, steady_state_levels


@dataclass(frozen=True)
class Comparison:
    """The physical model's figures at the log's operating point, and the identified
    static gains relative to it (identified / physical - 1)."""

    physical: Analysis
    levels: tuple[float, float, float, float]
    gain_error: np.ndarray


def operating_levels(op: Mapping[str, float], p: PlantParams, v_default: Sequence[float]
                     ) -> tuple[float, float, float, float]:
    """Levels (cm) at the operating point `op` (normalized log values by name)."""
    v = tuple(op.get(f"u{i + 1}", v_default[i] / FULL_SCALE_V) * FULL_SCALE_V for i in range(2))
    steady = steady_state_levels(v, p)
    h = [op[f"y{i + 1}"] * FULL_SCALE_V / p.kc if f"y{i + 1}" in op else steady[i] for i in range(4)]
    if any(not 0 < x <= p.hmax for x in h):
        raise PlantError("the log's first row is not an operating point of the process "
                         f"(levels {', '.join(f'{x:.2f}' for x in h)} cm)")
    return (h[0], h[1], h[2], h[3])


def closest_setting(op: Mapping[str, float]) -> Setting:
    """The named setting whose steady state at the logged inputs is nearest the logged
    lower levels (what a log from `quadtank run --par minphase` was run on)."""
    def distance(s: Setting) -> float:
        h = operating_levels({k: v for k, v in op.items() if k in ("u1", "u2")}, s.params, s.op.u)
        return sum((op[f"y{i}"] * FULL_SCALE_V / s.params.kc - h[i - 1]) ** 2
                   for i in (1, 2) if f"y{i}" in op)
    return min(SETTINGS.values(), key=distance)


def compare(op: Mapping[str, float], p: PlantParams, gains: np.ndarray,
            inputs: tuple[str, ...], outputs: tuple[str, ...], v_default: Sequence[float] = (3.0, 3.0)
            ) -> Comparison:
    """Linearize `p` at the operating point and set the identified gains beside it."""
    levels = operating_levels(op, p, v_default)
    a = analyze(p, levels)
    phys = np.array([[a.static_gains[int(o[1]) - 1, int(i[1]) - 1] for i in inputs] for o in outputs])
    return Comparison(a, levels, gains / phys - 1.0)


def physical_time_constants(a: Analysis, output: str, input: str) -> list[float]:
    """The physical element's time constants, largest first."""
    e = a.G[int(output[1]) - 1][int(input[1]) - 1]
    return sorted(e.lags, reverse=True)


__all__ = ["Comparison", "closest_setting", "compare", "operating_levels", "physical_time_constants",
           "time_constants"]
