"""The in-process simulator behind the process-backend interface (kind "Simul").

It speaks the same normalized units as a DAQ: the loop writes u in [0, 1] (10 u
volts to the pumps) and reads y = kc h / 10.  Between samples the nonlinear model is
integrated accurately with the inputs held (johansson.advance), so the result does
not depend on the sampling time beyond the zero-order hold.  It also offers what a
real rig cannot do from software (B7): pour water, change a valve, a cross-section
or an outlet while running, and jump back to the operating point on Reset.

The quadruple tank has the IST rig's two disturbance pumps too (core.disturbance:
pump i pours into tank i, by the rig's own simulator's law): `set_disturbances`
takes them as an IST backend does (fractions of full PWM, quantized to its 8 bits),
and `safe_state` and Reset stop them.

Any plant of core.plants runs behind it (:meth:`SimBackend.for_plant`): its sensors
are read as y = volts / 10 (y3, y4 read 0 on a two-tank rig) and pump i gets
u_i times the pump's full scale (22 V on a Quanser amplifier).  The quadruple tank
built from PlantParams keeps calling core.plants.johansson directly, bit for bit as before
(one with a real-rig effect on runs through the plant interface).
"""

from __future__ import annotations

import random

from quadtank_tui.core import disturbance as dist
from quadtank_tui.core import faults as fx
from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError
from quadtank_tui.core.plants.johansson import PlantParams, add_water, advance
from quadtank_tui.core.plants import Plant, QuadTank
from quadtank_tui.engine.backend import Levels4, Pair, ProcessBackend


class SimBackend(ProcessBackend):
    """The nonlinear four-tank model as a process.

    params : physical constants (cm, cm^2, V, s)
    levels : initial levels h1..h4, cm (the operating point for Reset)
    """

    kind = "Simul"
    description = "simulator"

    def __init__(self, params: PlantParams, levels: tuple[float, ...]) -> None:
        self._p = params
        self._plant: Plant | None = None  # None: the quadruple tank of self._p
        # One level per tank of the plant: 4 for the quadruple tank, 2 for a two-tank rig.
        self._op: tuple[float, ...] = tuple(float(x) for x in levels)
        self._h: tuple[float, ...] = self._op
        self._v: tuple[float, ...] = (0.0, 0.0)
        self._faults = fx.Faults()
        self._t = 0.0  # process time, s (sensor drift counts from it)
        self._rng = random.Random(0)  # sensor noise, reproducible run to run
        #: the disturbance pumps' duties d1, d2 (core.disturbance), 8-bit quantized
        self.disturbances: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def for_plant(cls, plant: Plant, levels: tuple[float, ...]) -> SimBackend:
        """Any plant of core.plants, at `levels` (its own length unit)."""
        if isinstance(plant, QuadTank) and not plant.effects_on:
            return cls(plant.params, levels)
        sim = cls(PlantParams(), (0.0, 0.0, 0.0, 0.0))
        sim.set_plant(plant, levels)
        sim.set_levels(levels)  # the water starts at the operating point whatever the tank count
        return sim

    # --- the backend interface ---------------------------------------------------------

    def read_levels(self) -> Levels4:
        y = self._true_levels()
        if not self._faults.active:  # (Faults' own bool, without its call: read every sample)
            return y
        normal = [self._rng.gauss(0.0, 1.0) for _ in y]
        m = fx.measure(y, self._faults, self._t, normal)
        return (m[0], m[1], m[2], m[3])

    def _true_levels(self) -> Levels4:
        if self._plant is not None:
            y = [v / FULL_SCALE_V for v in self._plant.output(self._h)][:4]
            y += [0.0] * (4 - len(y))
            return (y[0], y[1], y[2], y[3])
        kc = self._p.kc
        h = self._h
        return (kc * h[0] / FULL_SCALE_V, kc * h[1] / FULL_SCALE_V,
                kc * h[2] / FULL_SCALE_V, kc * h[3] / FULL_SCALE_V)

    def write_pumps(self, u: Pair) -> None:
        if self._plant is not None:
            self._v = tuple(s.full_scale * float(x) for s, x in zip(self._plant.inputs, u))
            return
        self._v = (FULL_SCALE_V * float(u[0]), FULL_SCALE_V * float(u[1]))

    def safe_state(self) -> None:
        self._v = tuple(0.0 for _ in self._v)
        self.disturbances = (0.0, 0.0)

    def elapse(self, dt: float) -> None:
        """Integrate dt seconds with the pump voltages (and the disturbance pumps) held."""
        self._t += dt
        d = self.disturbances
        if self._faults.active or d[0] or d[1]:  # (bool(Faults) and any(d), without the calls)
            plant = self.plant  # built once: for the quadruple tank each `plant` is a new QuadTank
            drifted = fx.drift_valves(plant, self._faults, dt)
            if drifted is not plant:
                self.set_plant(drifted)
            inflow = dist.IST.inflow(d) if d[0] or d[1] else ()
            self._h = fx.advance(drifted, self._faults, self._h, self._v, dt, inflow)
            return
        if self._plant is not None:
            self._h = self._plant.advance(self._h, self._v, dt)
            return
        self._h = advance(self._h, self._v, dt, self._p)

    # --- what only a simulation can do ---------------------------------------------------

    @property
    def params(self) -> PlantParams:
        """The quadruple tank's constants (PlantError for another plant: use `plant`)."""
        if self._plant is not None:
            raise PlantError(f"the simulated plant is a {self._plant.kind}, not the quadruple tank")
        return self._p

    @property
    def plant(self) -> Plant:
        """The simulated plant through the plant interface."""
        return QuadTank(self._p) if self._plant is None else self._plant

    @property
    def levels_cm(self) -> tuple[float, ...]:
        """h1..h4, cm (a plant of core.plants: its own levels, in its own unit)."""
        return self._h

    @property
    def voltages(self) -> tuple[float, ...]:
        """Pump voltages being applied, V (one per pump of the plant)."""
        return self._v

    def set_params(self, params: PlantParams, operating_levels: tuple[float, ...] | None = None) -> None:
        """New physical constants (a valve turned, a tank or outlet changed) with the
        water where it is; the levels are clipped to a lower tank height."""
        self._p = params
        self._h = tuple(min(max(x, 0.0), params.hmax) for x in self._h)
        if operating_levels is not None:
            self._op = tuple(float(x) for x in operating_levels)

    def set_plant(self, plant: Plant, operating_levels: tuple[float, ...] | None = None) -> None:
        """Another plant (or new constants of it) with the water where it is, when the
        tank count agrees; the operating levels when given (Reset goes there)."""
        n = len(plant.states)
        if isinstance(plant, QuadTank) and not plant.effects_on:  # with an effect: through the interface
            if len(self._h) != 4:
                self._h = tuple(float(x) for x in (operating_levels or (0.0,) * 4))
                self._v = (0.0, 0.0)
            self._plant = None
            self.set_params(plant.params, operating_levels)
            return
        if operating_levels is not None:
            self._op = plant.clip(operating_levels)
        self._h = plant.clip(self._h) if len(self._h) == n else self._op
        if len(self._v) != len(plant.inputs):
            self._v = tuple(0.0 for _ in plant.inputs)
        self._plant = plant

    # --- faults (core.faults) ----------------------------------------------------------------

    @property
    def faults(self) -> fx.Faults:
        return self._faults

    def set_fault(self, fault: fx.Fault) -> fx.Fault:
        """Switch a fault on now (replacing one of the same kind on the same target);
        FaultError if this plant cannot have it.  Returns it as it began."""
        began = fx.switched(fault, self.plant, self._t, self._true_levels())
        self._faults = self._faults.on(began)
        return began

    def clear_fault(self, kind: str, target: int) -> bool:
        """Switch a fault off; False if it was not on."""
        before = self._faults
        self._faults = before.off(kind, target)
        return self._faults != before

    # --- the disturbance pumps (core.disturbance) ----------------------------------------

    def set_disturbances(self, d1: float | None, d2: float | None) -> None:
        """The disturbance pumps at fractions d1, d2 of full PWM (None: as it is), from
        now on; ValueError for a value outside 0..1 or a plant without them."""
        if self.plant.kind != "quadtank":
            raise ValueError(f"the {self.plant.kind} plant has no disturbance pumps (the IST rig's pour into "
                             "tanks 1 and 2 of the quadruple tank)")
        self.disturbances = dist.updated(self.disturbances, d1, d2)

    def add_water(self, tank: int, amount: float) -> None:
        """Pour `amount` (normalized level, negative drains) into tank 1..n."""
        if self._plant is None:
            self._h = add_water(self._h, tank, amount * FULL_SCALE_V / self._p.kc, self._p)
            return
        n = len(self._h)
        if tank not in range(1, n + 1):
            raise PlantError(f"tank must be 1..{n}, got {tank}")
        unit = [1.0 if i == tank - 1 else 0.0 for i in range(n)]
        gain = self._plant.output(unit)[tank - 1]  # sensor volts per level unit
        h = list(self._h)
        h[tank - 1] += amount * FULL_SCALE_V / gain
        self._h = self._plant.clip(h)

    def set_levels(self, levels: tuple[float, ...]) -> None:
        """Put the water at `levels` (cm), e.g. a steady state to start from."""
        if self._plant is not None:
            self._h = self._plant.clip(levels)
            return
        self._h = tuple(min(max(float(x), 0.0), self._p.hmax) for x in levels)

    def reset(self) -> None:
        """Back to the operating point with the pumps off (Reset, M2)."""
        if self._plant is not None:
            self._h = self._plant.clip(self._op)
        else:
            self._h = tuple(min(x, self._p.hmax) for x in self._op)
        self._v = tuple(0.0 for _ in self._v)
        self.disturbances = (0.0, 0.0)
