"""State feedback on the quadruple tank, in the loop's normalized units.

The design model is the linearization at the steady state of the chosen lower levels
(core.analysis, Nunes 2.2), in cm and V, states h1..h4 (all four measured), tracked
outputs h1 and h2, pumps 0..10 V.  The upper tanks are filled by one pump each
(tank 3 by pump 2, tank 4 by pump 1), so each gets Desautel's tank-level saturation:
above (top - margin) its pump is capped at the voltage that holds it at
(top - 1.5 margin) (3.2.2: held a little below the trigger, so the limit lets go).

The engine works in normalized units (y = kc h / 10, u = V / 10); this adapter converts.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from quadtank_tui.core.analysis import linearize
from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError
from quadtank_tui.core.plants.johansson import PlantParams, steady_state_inputs
from quadtank_tui.core.controllers.statefb.tracking import AntiWindup, LevelLimit, StateFeedback, u_ssmax
from quadtank_tui.core.controllers.statefb.placement import Design, PlacementError, OperatingModel, design
from quadtank_tui.core.controllers.statefb.settings import StateFeedbackParams
from quadtank_tui.core.ranges import ParameterError

Pair = tuple[float, float]
SECTION = "STATE FEEDBACK"


def operating_model(plant: PlantParams, s: StateFeedbackParams) -> OperatingModel:
    """The linear model at the steady state of (Level1, Level2); ParameterError names
    the level when that state cannot be held (a pump would run backwards, a tank
    overflow)."""
    try:
        op = steady_state_inputs(s.level1, s.level2, plant)
        lin = linearize(plant, op.x)
    except PlantError as exc:
        raise ParameterError(f"{SECTION}.Level1", f"cannot linearize there: {exc}") from None
    if max(op.u) > FULL_SCALE_V:
        raise ParameterError(f"{SECTION}.Level1",
                             f"levels ({s.level1:g}, {s.level2:g}) cm need {max(op.u):.3g} V, above {FULL_SCALE_V:g} V")
    C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])  # h1, h2 in cm
    return OperatingModel(lin.A, lin.B, C, np.array(op.x), np.array(op.u),
                          u_min=np.zeros(2), u_max=np.full(2, FULL_SCALE_V))


def level_limits(plant: PlantParams, margin: float) -> tuple[LevelLimit, ...]:
    """Tank-level saturation of the upper tanks (state 2 <- pump 2, state 3 <- pump 1)."""
    trigger = plant.hmax - margin
    hold = max(plant.hmax - 1.5 * margin, 0.0)
    out = []
    for state, pump, outlet, feed in ((2, 1, plant.a3, (1 - plant.gamma2) * plant.k2),
                                      (3, 0, plant.a4, (1 - plant.gamma1) * plant.k1)):
        if feed > 0 and trigger > 0:
            out.append(LevelLimit(state, pump, trigger, u_ssmax(outlet, feed, hold, plant.g)))
    return tuple(out)


def design_for(plant: PlantParams, s: StateFeedbackParams, h: float) -> Design:
    """The design these settings ask for at sampling time h (s); ParameterError names
    the key to change when there is none."""
    return design_with(operating_model(plant, s), s, h)


def design_with(model: OperatingModel, s: StateFeedbackParams, h: float) -> Design:
    """The design of `model` with these settings; ParameterError names the key."""
    try:
        return design(model, h, settling_time=s.settling_time, poles=s.pole_values(), use_zeros=s.use_zeros)
    except PlacementError as exc:
        key = "Poles" if s.pole_values() or "poles" in str(exc) else "Ts"
        raise ParameterError(f"{SECTION}.{key}", str(exc)) from None


@dataclass(frozen=True)
class StateFeedbackInfo:
    """What the controller box shows: the gains in use, the poles, delta, and which
    limit acted in the last sample ("", "pump", "level")."""

    L1: tuple[tuple[float, ...], ...]
    L2: tuple[tuple[float, ...], ...]
    poles_s: tuple[complex, ...]
    poles_z: tuple[complex, ...]
    delta: float
    x_e: tuple[float, ...]
    u_e: tuple[float, ...]
    limited: str = ""


def info_of(d: Design, limited: str = "") -> StateFeedbackInfo:
    def rows(M: np.ndarray) -> tuple[tuple[float, ...], ...]:
        return tuple(tuple(float(v) for v in r) for r in M)

    return StateFeedbackInfo(
        rows(d.L1), rows(d.L2), tuple(complex(p) for p in d.poles_s),
        tuple(complex(p) for p in d.placed_poles()), float(d.delta),
        tuple(float(x) for x in d.model.x_e), tuple(float(u) for u in d.model.u_e), limited)


class NormalizedStateFeedback:
    """A state feedback the loop steps in its normalized units (r, y, u in 0..1):
    a plant's adapter says how they convert to the design's (`_levels`, `_refs`,
    `_volts`, `_normalized`) and keeps `_ctrl`, `settings` and `info`."""

    _ctrl: StateFeedback
    settings: StateFeedbackParams
    info: StateFeedbackInfo

    def _levels(self, y: Sequence[float]) -> np.ndarray:
        raise NotImplementedError

    def _refs(self, r: Sequence[float]) -> np.ndarray:
        raise NotImplementedError

    def _volts(self, u: Sequence[float]) -> np.ndarray:
        raise NotImplementedError

    def _normalized(self, volts: np.ndarray) -> Pair:
        raise NotImplementedError

    def _set_limits(self, settings: StateFeedbackParams, limits: Sequence[LevelLimit]) -> None:
        self.settings = settings
        self._ctrl.set_limits(l3=settings.l3, anti_windup=_aw(settings), level_limits=limits)

    def compute(self, r: Sequence[float], y: Sequence[float]) -> Pair:
        """Pump inputs (normalized) for references r1, r2 and levels y1..y4."""
        return self._normalized(self._ctrl.output(self._refs(r), self._levels(y)).u)

    def update(self, r: Sequence[float], y: Sequence[float], u_applied: Sequence[float]) -> None:
        """Automatic: advance the integrators after u went out."""
        rc, x = self._refs(r), self._levels(y)
        out = self._ctrl.output(rc, x)
        self._ctrl.update(rc, x, out, self._volts(u_applied))
        limited = "level" if any(out.level_held) else "pump" if any(out.pump_limited) else ""
        if limited != self.info.limited:
            self.info = _with_limited(self.info, limited)

    def track(self, y: Sequence[float], u_applied: Sequence[float]) -> None:
        """Manual, or the switch to this type: start where the pumps are (3.1.10)."""
        self._ctrl.track(self._levels(y), self._volts(u_applied))
        if self.info.limited:
            self.info = _with_limited(self.info, "")

    def reset(self) -> None:
        self._ctrl.reset()

    @property
    def controller(self) -> StateFeedback:
        return self._ctrl


class QuadTankStateFeedback(NormalizedStateFeedback):
    """The controller type "State feedback" for the loop (normalized r, y, u)."""

    def __init__(self, plant: PlantParams, settings: StateFeedbackParams, h: float) -> None:
        self._plant = plant
        d = design_for(plant, settings, h)
        self.settings = settings
        self._ctrl = StateFeedback(d, l3=settings.l3, anti_windup=_aw(settings),
                                   level_limits=level_limits(plant, settings.level_margin))
        self.info = info_of(d)

    def configure(self, plant: PlantParams, settings: StateFeedbackParams, d: Design | float) -> None:
        """Redesign between samples (bumpless); `d` is the new design (design_for) or
        the sampling time to make it at.  Refuses before changing anything."""
        if not isinstance(d, Design):
            d = design_for(plant, settings, d)
        self._plant = plant
        self._ctrl.redesign(d)
        self._set_limits(settings, level_limits(plant, settings.level_margin))
        self.info = info_of(d)

    # --- normalized units: y = kc h / 10, u = V / 10 -----------------------------------

    def _levels(self, y: Sequence[float]) -> np.ndarray:
        return np.asarray(y, dtype=float) * FULL_SCALE_V / self._plant.kc

    def _refs(self, r: Sequence[float]) -> np.ndarray:
        return self._levels(r)

    def _volts(self, u: Sequence[float]) -> np.ndarray:
        return np.asarray(u, dtype=float) * FULL_SCALE_V

    def _normalized(self, volts: np.ndarray) -> Pair:
        return (float(volts[0]) / FULL_SCALE_V, float(volts[1]) / FULL_SCALE_V)


def _aw(s: StateFeedbackParams) -> AntiWindup:
    return AntiWindup.SMART if s.smart else AntiWindup.PLAIN


def _with_limited(info: StateFeedbackInfo, limited: str) -> StateFeedbackInfo:
    return replace(info, limited=limited)
