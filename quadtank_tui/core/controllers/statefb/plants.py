"""State feedback on the other plants of core.plants (the coupled tanks), in the
loop's normalized units.

The design model is the plant's own linearization (core.plants) at its operating
levels (the PLANT section's Level1..n, the point Setup shows), every level measured,
one integrator per controlled tank (`Plant.controlled`):

- the cascade (Desautel's CTP, chapter 3): one pump, both levels, the integrator on
  the lower tank; at x1 = 15 cm, T = 0.1 s, Ts = 20 s this is his design 3.4;
- the two-input rig (Murray-Smith): two pumps, both levels, two integrators.

Units are the plant's (cm or m, V).  Tank-level saturation (3.2.2) acts on each
tank a pump fills directly: above (top - margin) that pump is capped at the voltage
that, with that pump alone, holds the tank at (top - 1.5 margin), found from the
plant's own steady state (for the cascade this is Desautel's
U_ssmax = alpha1 sqrt(2 g x_max) / beta1).  The margin is given in cm
(`LevelMargin`) and converted for a plant in metres.

The loop reads y_i = (sensor i volts) / 10 and writes pump i as u_i times its full
scale (22 V on the Quanser amplifier); the reference of a controlled tank i is r_i,
so the cascade's lower tank follows REFERENCE TWO.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError
from quadtank_tui.core.plants.base import Plant
from quadtank_tui.core.controllers.statefb.tracking import LevelLimit, StateFeedback
from quadtank_tui.core.controllers.statefb.placement import Design, OperatingModel
from quadtank_tui.core.controllers.statefb.quadtank import NormalizedStateFeedback, _aw, design_with, info_of
from quadtank_tui.core.controllers.statefb.settings import StateFeedbackParams
from quadtank_tui.core.ranges import ParameterError

Pair = tuple[float, float]

#: Length units a plant may use, in cm (LevelMargin is given in cm).
_CM_PER_UNIT = {"cm": 1.0, "m": 100.0}


def operating_model(plant: Plant, levels: Sequence[float]) -> OperatingModel:
    """The linear model at the steady state through the controlled tanks' operating
    levels (the other levels follow); ParameterError names PLANT.LevelN when no pump
    setting holds them."""
    given = [float(x) if i in plant.controlled else None for i, x in enumerate(levels)]
    try:
        op = plant.steady_inputs(given)
    except PlantError as exc:
        key = f"PLANT.Level{plant.controlled[0] + 1}"
        raise ParameterError(key, f"cannot linearize there: {exc}") from None
    lin = plant.linearize(op.x, op.u)
    C = np.eye(len(plant.states))[list(plant.controlled)]
    return OperatingModel(lin.A, lin.B, C, np.array(op.x), np.array(op.u),
                          u_min=np.array([s.lo for s in plant.inputs]),
                          u_max=np.array([s.hi for s in plant.inputs]))


def hold_voltage(plant: Plant, tank: int, pump: int, level: float) -> float | None:
    """The voltage of `pump` alone (the others at 0) at which `tank` settles at
    `level`; None when even the full pump cannot fill it that high.  Bisection on the
    plant's steady state, which rises with the pump voltage."""
    hi = plant.inputs[pump].hi

    def settled(v: float) -> float:
        u = [0.0] * len(plant.inputs)
        u[pump] = v
        return plant.steady_state(u)[tank]

    if settled(hi) < level:
        return None
    lo = 0.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if settled(mid) < level:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def level_limits(plant: Plant, margin_cm: float) -> tuple[LevelLimit, ...]:
    """Tank-level saturation of every tank a pump fills directly (3.2.2)."""
    out = []
    for pump in plant.layout().pumps:
        for tank, _share in pump.feeds:
            state = plant.states[tank]
            margin = margin_cm / _CM_PER_UNIT.get(state.unit, 1.0)
            trigger = state.hi - margin
            hold = max(state.hi - 1.5 * margin, 0.0)
            if trigger <= 0:
                continue
            u_hold = hold_voltage(plant, tank, pump.input, hold)
            if u_hold is not None:
                out.append(LevelLimit(tank, pump.input, trigger, u_hold))
    return tuple(out)


def design_for(plant: Plant, levels: Sequence[float], s: StateFeedbackParams, h: float) -> Design:
    """The design these settings ask for on `plant` at sampling time h (s);
    ParameterError names the key to change when there is none."""
    return design_with(operating_model(plant, levels), s, h)


class PlantStateFeedback(NormalizedStateFeedback):
    """The controller type "State feedback" on a plant of core.plants (normalized r,
    y, u), the same interface as QuadTankStateFeedback."""

    def __init__(self, plant: Plant, levels: Sequence[float], settings: StateFeedbackParams, h: float) -> None:
        d = design_for(plant, levels, settings, h)
        self._set_plant(plant)
        self.settings = settings
        self._ctrl = StateFeedback(d, l3=settings.l3, anti_windup=_aw(settings),
                                   level_limits=level_limits(plant, settings.level_margin))
        self.info = info_of(d)

    def _set_plant(self, plant: Plant) -> None:
        self._plant = plant
        n = len(plant.states)
        #: sensor volts per level unit, tank by tank (every plant's sensors are linear)
        self._gain = np.array([plant.output(np.eye(n)[i])[i] for i in range(n)])
        self._scale = np.array([s.full_scale for s in plant.inputs])

    def configure(self, plant: Plant, levels: Sequence[float], settings: StateFeedbackParams,
                  d: Design | float) -> None:
        """Redesign between samples (bumpless); `d` is the new design or the sampling
        time to make it at.  Refuses before changing anything."""
        if not isinstance(d, Design):
            d = design_for(plant, levels, settings, d)
        if len(plant.states) != len(self._plant.states) or len(plant.inputs) != len(self._plant.inputs):
            raise ParameterError("CONTROL.Type", "another plant: choose the state feedback again")
        self._ctrl.redesign(d)
        self._set_plant(plant)
        self._set_limits(settings, level_limits(plant, settings.level_margin))
        self.info = info_of(d)

    # --- normalized units: y_i = sensor volts / 10, u_i = volts / full scale ---------------

    def _levels(self, y: Sequence[float]) -> np.ndarray:
        n = len(self._gain)
        return np.asarray(y[:n], dtype=float) * FULL_SCALE_V / self._gain

    def _refs(self, r: Sequence[float]) -> np.ndarray:
        """The tracked tanks' references in level units (r_i for tank i)."""
        idx = list(self._plant.controlled)
        return np.asarray([r[i] for i in idx], dtype=float) * FULL_SCALE_V / self._gain[idx]

    def _volts(self, u: Sequence[float]) -> np.ndarray:
        return np.asarray(u[: len(self._scale)], dtype=float) * self._scale

    def _normalized(self, volts: np.ndarray) -> Pair:
        u = [float(v) for v in volts / self._scale] + [0.0, 0.0]
        return (u[0], u[1])
