"""The in-process simulator behind the process-backend interface (kind "Simul").

It speaks the same normalized units as a DAQ: the loop writes u in [0, 1] (10 u
volts to the pumps) and reads y = kc h / 10.  Between samples the nonlinear model is
integrated accurately with the inputs held (core.plant.advance), so the result does
not depend on the sampling time beyond the zero-order hold.  It also offers what a
real rig cannot do from software (B7): pour water, change a valve, a cross-section
or an outlet while running, and jump back to the operating point on Reset.
"""

from __future__ import annotations

from quadtank_tui.core.plant import (
    FULL_SCALE_V,
    Levels,
    PlantParams,
    add_water,
    advance,
)
from quadtank_tui.engine.backend import Levels4, Pair, ProcessBackend


class SimBackend(ProcessBackend):
    """The nonlinear four-tank model as a process.

    params : physical constants (cm, cm^2, V, s)
    levels : initial levels h1..h4, cm (the operating point for Reset)
    """

    kind = "Simul"
    description = "simulator"

    def __init__(self, params: PlantParams, levels: Levels) -> None:
        self._p = params
        self._op: Levels = tuple(float(x) for x in levels)  # type: ignore[assignment]
        self._h: Levels = self._op
        self._v: tuple[float, float] = (0.0, 0.0)

    # --- the backend interface ---------------------------------------------------------

    def read_levels(self) -> Levels4:
        kc = self._p.kc
        h = self._h
        return (kc * h[0] / FULL_SCALE_V, kc * h[1] / FULL_SCALE_V,
                kc * h[2] / FULL_SCALE_V, kc * h[3] / FULL_SCALE_V)

    def write_pumps(self, u: Pair) -> None:
        self._v = (FULL_SCALE_V * float(u[0]), FULL_SCALE_V * float(u[1]))

    def safe_state(self) -> None:
        self._v = (0.0, 0.0)

    def elapse(self, dt: float) -> None:
        """Integrate dt seconds with the pump voltages held."""
        self._h = advance(self._h, self._v, dt, self._p)

    # --- what only a simulation can do ---------------------------------------------------

    @property
    def params(self) -> PlantParams:
        return self._p

    @property
    def levels_cm(self) -> Levels:
        """h1..h4, cm."""
        return self._h

    @property
    def voltages(self) -> tuple[float, float]:
        """Pump voltages being applied, V."""
        return self._v

    def set_params(self, params: PlantParams, operating_levels: Levels | None = None) -> None:
        """New physical constants (a valve turned, a tank or outlet changed) with the
        water where it is; the levels are clipped to a lower tank height."""
        self._p = params
        self._h = tuple(min(max(x, 0.0), params.hmax) for x in self._h)  # type: ignore[assignment]
        if operating_levels is not None:
            self._op = tuple(float(x) for x in operating_levels)  # type: ignore[assignment]

    def add_water(self, tank: int, amount: float) -> None:
        """Pour `amount` (normalized level, negative drains) into tank 1..4."""
        self._h = add_water(self._h, tank, amount * FULL_SCALE_V / self._p.kc, self._p)

    def set_levels(self, levels: Levels) -> None:
        """Put the water at `levels` (cm), e.g. a steady state to start from."""
        self._h = tuple(min(max(float(x), 0.0), self._p.hmax) for x in levels)  # type: ignore[assignment]

    def reset(self) -> None:
        """Back to the operating point with the pumps off (Reset, M2)."""
        self._h = tuple(min(x, self._p.hmax) for x in self._op)  # type: ignore[assignment]
        self._v = (0.0, 0.0)
