"""The controller type "MPC" in the loop: core.controllers.mpc's controller in the loop's
normalized units, with the same four calls as the state feedback (compute, update,
track, reset) so engine/loop.py's `_sample` runs either the same way.

The loop reads y_i = (sensor i volts) / 10 and writes pump i as u_i times its full
scale; the MPC works in the plant's units (levels, volts).  The references are
r1, r2 for the tracked tanks (tank i follows r_i, as with the state feedback); with
preview on, the loop hands over the generators' next N samples (a wave is known in
advance) before computing.  A failed solve never raises (core.controllers.mpc holds the last
input, within limits, and counts it); `info` carries the counts and solve times to
the snapshot.
"""

from __future__ import annotations

import copy
from collections import deque
from typing import Sequence

import numpy as np

from quadtank_tui.core.controllers.mpc.predictive import MPC, MPCStats, design_mpc, percentiles
from quadtank_tui.core.controllers.mpc.info import MPCInfo
from quadtank_tui.core.controllers.mpc.model import plant_in_use
from quadtank_tui.core.controllers.mpc.simulate import sensor_gains
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.controllers.signals import Generator

Pair = tuple[float, float]

#: Solve times kept for the percentiles the controller box shows.
KEPT = 1000
#: A solve longer than this share of the sampling time is counted as slow.
BUDGET = 0.1
#: The percentiles are worked out again every this many solves (and at each of the
#: first ones): over a window of KEPT solves they move little from one to the next,
#: and working them out every sample cost 0.3 ms, a third of a solve.
PERCENTILES_EVERY = 10


def future_references(gens: Sequence[Generator], n: int, every: int = 1) -> np.ndarray:
    """The generators' values for this sample and the n after it, `every` samples
    apart (rows: the MPC's prediction grid), normalized; copies are advanced, the
    loop's own generators do not move."""
    if every == 1:
        return np.array([copy.deepcopy(g).take(n + 1) for g in gens]).T
    rows = []
    for g in gens:
        c = copy.deepcopy(g)
        values = []
        for _ in range(n + 1):
            values.append(c.value())
            c.advance_by(every)
        rows.append(values)
    return np.array(rows).T


class LoopMPC:
    """The MPC of `params` on its plant at its operating point and sampling time
    (ParameterError, naming the key, if there is no design)."""

    def __init__(self, params: Parameters, stats: MPCStats | None = None) -> None:
        plant, levels = plant_in_use(params)
        d = design_mpc(plant, levels, params.mpc, params.tsamp)
        self.mpc = MPC(d)
        if stats is not None:  # a redesign keeps the counts
            self.mpc.stats = stats
        self._plant = plant
        self._gain = sensor_gains(plant)
        self._scale = np.array([s.full_scale for s in plant.inputs])
        self._tracked = list(plant.controlled)
        self._times: deque[float] = deque(maxlen=KEPT)
        self._max = 0.0
        self._slow = 0
        self._p50_p99 = (0.0, 0.0)
        self._future: np.ndarray | None = None
        mdl = d.model
        self.info = MPCInfo(d.settings.horizon, d.settings.moves, tuple(float(x) for x in mdl.x_e),
                            tuple(float(u) for u in mdl.u_e), note=mdl.note, step_s=d.prediction.T)
        self._refresh("", 0.0)

    def keep_counts(self, stats: MPCStats) -> None:
        """A redesign designed elsewhere keeps the counts of the MPC it replaces."""
        self.mpc.stats = stats
        self._refresh("", 0.0)

    @property
    def horizon(self) -> int:
        return self.mpc.design.settings.horizon

    @property
    def wants_preview(self) -> bool:
        return self.mpc.design.settings.preview

    def preview(self, gens: Sequence[Generator]) -> None:
        """The generators' references r1, r2 for this sample and the N prediction steps
        after it, for the next `compute` only."""
        self._future = future_references(gens, self.horizon, self.mpc.design.step_samples)

    # --- normalized units ------------------------------------------------------------------

    def _levels(self, y: Sequence[float]) -> np.ndarray:
        return np.asarray(y[: len(self._gain)], dtype=float) * FULL_SCALE_V / self._gain

    def _refs(self, r: np.ndarray) -> np.ndarray:
        """Rows of r1, r2 (normalized) -> rows of the tracked tanks' levels."""
        g = self._gain[self._tracked]
        return np.atleast_2d(r)[:, self._tracked] * FULL_SCALE_V / g

    def _volts(self, u: Sequence[float]) -> np.ndarray:
        return np.asarray(u[: len(self._scale)], dtype=float) * self._scale

    def _normalized(self, volts: np.ndarray) -> Pair:
        u = [float(v) for v in volts / self._scale] + [0.0, 0.0]
        return (u[0], u[1])

    # --- the loop's calls -----------------------------------------------------------------------

    def compute(self, r: Sequence[float], y: Sequence[float]) -> Pair:
        """Pump inputs (normalized) for references r1, r2 and levels y1..y4: one solve
        (a failed one holds the last input and is counted, never raises)."""
        future, self._future = self._future, None
        refs = self._refs(future if future is not None else np.asarray([list(r)], dtype=float))
        x = self._levels(y)
        step = self.mpc.step(x[list(self.mpc.design.model.measured)], refs)
        self._times.append(step.solve_time)
        self._max = max(self._max, step.solve_time)
        self._slow += int(step.solve_time > BUDGET * self.mpc.design.model.T)
        self._refresh(self.mpc.stats.last_status, step.slack)
        return self._normalized(step.u)

    def update(self, r: Sequence[float], y: Sequence[float], u_applied: Sequence[float]) -> None:
        """Automatic: the inputs that went out (an interlock may have held a pump)."""
        self.mpc.applied(self._volts(u_applied))

    def track(self, y: Sequence[float], u_applied: Sequence[float], automatic: bool = False) -> None:
        """Manual, or the switch to MPC: the estimate starts at the measured levels and
        the next move from the pumps in force (bumpless); `automatic`: a switch in
        Automatic, where the next move is the pumps in force even while the levels are
        still on their way to the references (core.controllers.mpc.MPC.track)."""
        self.mpc.track(self._levels(y), self._volts(u_applied), moving=automatic)

    def reset(self) -> None:
        """Reset: the disturbance estimate and the counts start again."""
        self.mpc.forget_disturbance()
        self.mpc.stats = MPCStats()
        self._times.clear()
        self._max, self._slow = 0.0, 0
        self._p50_p99 = (0.0, 0.0)
        self._refresh("", 0.0)

    def _refresh(self, status: str, slack: float) -> None:
        st = self.mpc.stats
        del st.times[:-KEPT], st.cpu_times[:-KEPT]  # the loop runs for hours: keep a window
        times = self._times
        if times and (len(times) <= PERCENTILES_EVERY or st.solves % PERCENTILES_EVERY == 0):
            p50, p99 = percentiles(times, (50, 99))
            self._p50_p99 = (p50 * 1e3, p99 * 1e3)
        p50, p99 = self._p50_p99
        self.info = MPCInfo(
            self.info.horizon, self.info.moves, self.info.x_e, self.info.u_e, solves=st.solves,
            faults=st.faults, slow=self._slow, last_ms=times[-1] * 1e3 if times else 0.0, p50_ms=p50,
            p99_ms=p99, max_ms=self._max * 1e3, status=status, slack=slack, note=self.info.note,
            step_s=self.info.step_s)
