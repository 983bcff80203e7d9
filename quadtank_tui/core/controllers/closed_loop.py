"""The one closed-loop simulator of a controller on a nonlinear plant, sample by
sample as the engine runs it in Automatic: read the levels, compute the pumps,
hold them over the sample while the plant (with the faults of the moment) advances.

The design preview (core.design.preview), the MPC comparison
(core.controllers.mpc.simulate) and the exercises run through it; the batch path
(core.batch) is its vectorized twin for many plants at once, tested against the
same steps (tests/core/design/test_robust.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from quadtank_tui.core import faults as fx
from quadtank_tui.core.plants.base import Plant

#: control(k, t, levels) -> pump volts (one per pump), as commanded
Control = Callable[[int, float, np.ndarray], "Sequence[float] | np.ndarray"]


@dataclass(frozen=True)
class Trajectory:
    """Samples k = 0..K-1 at t = k T: the levels read x (K, tanks) and the pumps
    commanded u (K, pumps) at each, the plant's units."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray


def simulate(plant: Plant, x0: Sequence[float], T: float, samples: int, control: Control, *,
             faults: Callable[[float], fx.Faults] | None = None,
             stop: Callable[[int], bool] | None = None) -> Trajectory:
    """Up to `samples` samples from levels x0 at sampling time T: the controller
    reads the levels and commands the pumps, the plant advances T with them held
    (core.faults.advance: exactly ``plant.advance`` without a fault; the plant
    saturates what is outside its range).  `faults(t)`: the faults acting from
    sample time t; `stop(k)`: asked after sample k, True ends the run there."""
    x = np.array(x0, dtype=float)
    xs: list[np.ndarray] = []
    us: list[np.ndarray] = []
    none = fx.Faults()
    for k in range(samples):
        t = k * T
        u = np.asarray(control(k, t, x), dtype=float)
        xs.append(x.copy())
        us.append(u.copy())
        acting = faults(t) if faults is not None else none
        x = np.array(fx.advance(plant, acting, x.tolist(), u.tolist(), T))
        if stop is not None and stop(k):
            break
    return Trajectory(np.arange(len(xs)) * T, np.array(xs), np.array(us))
