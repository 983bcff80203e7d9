"""The small interface every tank plant implements, and what it hands out.

A plant is a frozen dataclass of its physical constants with the model as methods:
state (levels, in the plant's own length unit), inputs (pump voltages, V), outputs
(sensor voltages, V), `rhs`, the steady state both ways, the linearization, the
limits, an accurate zero-order-hold step and a drawing description.  Everything is a
pure function of its arguments, so a plant can be shared between threads and
processes and compared by value.

Conventions shared by every plant (control.md, "The quadruple-tank process"):
- a pump does not run backwards and saturates at its range: inputs outside
  [lo, hi] act as the nearest limit;
- a tank never goes below its floor nor above its brim: water that would raise a
  full tank spills out of the process, an empty tank has no outflow;
- Torricelli's law q = c sqrt(2 g dh) is blended smoothly to 0 over the last film
  of head (see :func:`orifice_flow`), so nothing is infinitely stiff.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Sequence

from quadtank_tui.core.plants.common import (
    FULL_SCALE_V,
    OperatingPoint,
    PlantError,
    SteadyStateError,
    Vector,
    head_for_flow,
    orifice_flow,
    orifice_slope,
)
from quadtank_tui.core.plants.stepping import dopri_advance

if TYPE_CHECKING:
    from quadtank_tui.core.plants.linear import LinearModel


@dataclass(frozen=True)
class Signal:
    """A named state, input or output with its unit and range.

    full_scale : the value a normalized 1.0 stands for in the program's DAQ units
        (10 V for every analog signal of the original; a Quanser pump spans 22 V)
    """

    name: str
    unit: str
    lo: float
    hi: float
    full_scale: float = FULL_SCALE_V


# --- what the UI draws ------------------------------------------------------------------

@dataclass(frozen=True)
class TankView:
    """Tank `state` drawn in `column` (0 = left) and `row` (0 = bottom)."""

    label: str
    state: int
    column: int
    row: int


@dataclass(frozen=True)
class PumpView:
    """Pump `input`; `feeds` lists (tank state index, share) where share names the
    fraction of its flow ("gamma1", "1 - gamma1", "1")."""

    label: str
    input: int
    feeds: tuple[tuple[int, str], ...]


@dataclass(frozen=True)
class PipeView:
    """Water from tank `source` to tank `target` (None: out of the process, the
    basin); `two_way` when it can flow back (an orifice between tanks side by side)."""

    source: int
    target: int | None
    label: str
    two_way: bool = False


@dataclass(frozen=True)
class Layout:
    """A process image: the tanks, the pumps and the pipes between them."""

    tanks: tuple[TankView, ...]
    pumps: tuple[PumpView, ...]
    pipes: tuple[PipeView, ...]

    @property
    def columns(self) -> int:
        return 1 + max(t.column for t in self.tanks)

    @property
    def rows(self) -> int:
        return 1 + max(t.row for t in self.tanks)


# --- the interface ---------------------------------------------------------------------------

#: Local error tolerance of the ZOH step relative to the tank height: 1e-10 cm on
#: the quadruple tank's 20 cm (core.plants.johansson.ATOL), the same fraction on every plant.
RELATIVE_ATOL = 5e-12


class Plant(ABC):
    """A tank process.  Subclasses are frozen dataclasses of their constants."""

    #: Key used in `.par` files and on the command line ("quadtank", "coupled-cascade", ...).
    kind: str = ""
    #: One line for titles.
    title: str = ""
    #: The outputs the control loop acts on (the rest are measured only): the lower
    #: tanks of a quadruple tank, tank 2 of the cascade, both tanks side by side.
    controlled: ClassVar[tuple[int, ...]] = (0, 1)

    # --- description ------------------------------------------------------------------

    @property
    @abstractmethod
    def states(self) -> tuple[Signal, ...]:
        """Levels, with the floor and the brim of each tank."""

    @property
    @abstractmethod
    def inputs(self) -> tuple[Signal, ...]:
        """Pump voltages with the pump range."""

    @property
    @abstractmethod
    def outputs(self) -> tuple[Signal, ...]:
        """Sensor voltages, one per measured tank."""

    @abstractmethod
    def layout(self) -> Layout:
        """What a process image shows."""

    # --- what a fault acts on (core.faults) ---------------------------------------------

    #: The unit of each constant (what Setup's plant window shows next to it).
    units: ClassVar[dict[str, str]] = {}

    #: Name of the constant that sets each tank's outlet (its drain, or the orifice it
    #: empties through): a clogged outlet scales it.
    outlet_names: ClassVar[tuple[str, ...]] = ()
    #: Names of the valve splits (a drifting valve moves one), () without valves.
    valve_names: ClassVar[tuple[str, ...]] = ()
    #: Constants of effects a real rig shows (an overflow, a pump threshold, a
    #: sensor's range), off at 0: a `.par` file names them only when they are on.
    effect_names: ClassVar[tuple[str, ...]] = ()

    @property
    def gravity(self) -> float:
        """g in the plant's length unit per s^2."""
        return float(self.values()["g"])

    def area(self, i: int) -> float:
        """Cross-section of tank i (0-based), the length unit squared; 1 for a plant
        written per unit area (alpha_i = a_i / A_i), where an outlet area is alpha."""
        return 1.0

    def values(self) -> dict[str, float]:
        """The physical constants by name (what a `.par` file and Setup hold)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}  # type: ignore[arg-type]  # every concrete plant is a dataclass

    def with_values(self, **changes: float) -> Plant:
        """A copy with some constants changed (validated like the original)."""
        unknown = sorted(set(changes) - set(self.values()))
        if unknown:
            raise PlantError(f"{self.kind} has no constant {', '.join(unknown)}")
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]  # a concrete plant: a dataclass

    # --- the model ------------------------------------------------------------------------

    @abstractmethod
    def rhs(self, x: Sequence[float], u: Sequence[float]) -> Vector:
        """dx/dt of the nonlinear model (state units per second)."""

    @abstractmethod
    def output(self, x: Sequence[float]) -> Vector:
        """Sensor voltages at levels x."""

    @abstractmethod
    def jacobians(self, x0: Sequence[float], u0: Sequence[float]) -> tuple[Any, Any, Any]:
        """(A, B, C) of the linearization as nested lists (numpy-free core of it)."""

    @abstractmethod
    def steady_state(self, u: Sequence[float]) -> Vector:
        """Levels the process settles at with the pump voltages u held."""

    @abstractmethod
    def steady_inputs(self, levels: Sequence[float | None]) -> OperatingPoint:
        """Pump voltages that hold the given levels (None: a level left free), with the
        levels that result; SteadyStateError if no pump setting can."""

    def advance(self, x: Sequence[float], u: Sequence[float], dt: float) -> Vector:
        """Levels after dt seconds with u held (zero-order hold), accurate to the
        solver tolerance whatever dt (adaptive Dormand-Prince, levels projected onto
        their limits after each sub-step)."""
        lo = tuple(s.lo for s in self.states)
        hi = tuple(s.hi for s in self.states)
        atol = RELATIVE_ATOL * max(hi)
        uu = self.saturate(u)
        return dopri_advance(lambda y: self.rhs(y, uu), x, dt, lo, hi, rtol=1e-10, atol=atol)

    # --- derived ---------------------------------------------------------------------------

    def saturate(self, u: Sequence[float]) -> Vector:
        """u clipped to the pump ranges."""
        if len(u) != len(self.inputs):
            raise PlantError(f"{self.kind} has {len(self.inputs)} input(s), got {len(u)}")
        return tuple(min(max(float(v), s.lo), s.hi) for v, s in zip(u, self.inputs))

    def clip(self, x: Sequence[float]) -> Vector:
        """Levels projected onto [floor, brim]."""
        if len(x) != len(self.states):
            raise PlantError(f"{self.kind} has {len(self.states)} levels, got {len(x)}")
        return tuple(min(max(float(v), s.lo), s.hi) for v, s in zip(x, self.states))

    def linearize(self, x0: Sequence[float], u0: Sequence[float] | None = None) -> LinearModel:
        """The Jacobians about (x0, u0); deviations in state units, V and sensor V."""
        from quadtank_tui.core.plants.linear import LinearModel  # numpy: only when asked

        x0t = self.clip(x0)
        u0t = self.saturate(u0) if u0 is not None else tuple(0.0 for _ in self.inputs)
        A, B, C = self.jacobians(x0t, u0t)
        return LinearModel.of(A, B, C, x0=x0t, u0=u0t,
                              states=tuple(s.name for s in self.states),
                              inputs=tuple(s.name for s in self.inputs),
                              outputs=tuple(s.name for s in self.outputs))

    def linearize_at(self, op: OperatingPoint) -> LinearModel:
        """Linearization at an operating point."""
        return self.linearize(op.x, op.u)

    def control_model(self, x0: Sequence[float], u0: Sequence[float] | None = None) -> LinearModel:
        """The linearization from the pumps to the controlled outputs only (the
        transfer matrix a loop designer and ICAD work with)."""
        return self.linearize(x0, u0).select(self.controlled)


__all__ = [
    "FULL_SCALE_V", "Layout", "OperatingPoint", "PipeView", "Plant", "PlantError", "PumpView", "Signal",
    "SteadyStateError", "TankView", "Vector", "head_for_flow", "orifice_flow", "orifice_slope",
]
