"""The quadruple tank through the plant interface: Johansson's rig, and Desautel's.

:class:`QuadTank` presents core.plant (which stays as it is) unchanged: every method
calls the functions there, so a simulation through the interface is bit for bit the
one the program has always run.  :class:`DesautelQTP` is the same process in
Desautel's parameterization (001_..., 2.2.1 and Table 9)::

    x1' = b1 u1 - a1 sqrt(2 g x1) + a3 sqrt(2 g x3)      x3' = b3 u2 - a3 sqrt(2 g x3)
    x2' = b2 u2 - a2 sqrt(2 g x2) + a4 sqrt(2 g x4)      x4' = b4 u1 - a4 sqrt(2 g x4)

with alpha_i = a_i / A_i and beta_i the pump coefficient into tank i.  These are
Johansson's equations for tanks of unit cross-section (alpha3 in tank 1's equation is
a3/A1 there, a3/A3 in tank 3's: Desautel's form takes A1 = A3, A2 = A4), with
k1 = beta1 + beta4, gamma1 = beta1 / k1, k2 = beta2 + beta3, gamma2 = beta2 / k2, so
it reuses the tested model and stepping.  Areas only scale volumes, never levels.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any, ClassVar, Sequence

from quadtank_tui.core import plant as qt
from quadtank_tui.core.plant import FULL_SCALE_V, PlantError, PlantParams
from quadtank_tui.core.plants.base import (
    Layout,
    OperatingPoint,
    PipeView,
    Plant,
    PumpView,
    Signal,
    SteadyStateError,
    TankView,
    Vector,
    orifice_slope,
)

_LEVELS = ("h1", "h2", "h3", "h4")


class _FourTanks(Plant):
    """What both parameterizations share: the model is core.plant's."""

    def plant_params(self) -> PlantParams:
        raise NotImplementedError

    @property
    def pump_max(self) -> float:
        return FULL_SCALE_V

    @property
    def states(self) -> tuple[Signal, ...]:
        p = self.plant_params()
        return tuple(Signal(n, "cm", 0.0, p.hmax, p.hmax) for n in _LEVELS)

    @property
    def inputs(self) -> tuple[Signal, ...]:
        return (Signal("v1", "V", 0.0, self.pump_max, self.pump_max),
                Signal("v2", "V", 0.0, self.pump_max, self.pump_max))

    @property
    def outputs(self) -> tuple[Signal, ...]:
        p = self.plant_params()
        return tuple(Signal(f"y{i + 1}", "V", 0.0, p.kc * p.hmax) for i in range(4))

    def layout(self) -> Layout:
        tanks = (TankView("1", 0, 0, 0), TankView("2", 1, 1, 0), TankView("3", 2, 0, 1), TankView("4", 3, 1, 1))
        pumps = (PumpView("pump 1", 0, ((0, "gamma1"), (3, "1 - gamma1"))),
                 PumpView("pump 2", 1, ((1, "gamma2"), (2, "1 - gamma2"))))
        pipes = (PipeView(2, 0, "a3"), PipeView(3, 1, "a4"), PipeView(0, None, "a1"), PipeView(1, None, "a2"))
        return Layout(tanks, pumps, pipes)

    def rhs(self, x: Sequence[float], u: Sequence[float]) -> Vector:
        return qt.rhs(x, u, self.plant_params())

    def advance(self, x: Sequence[float], u: Sequence[float], dt: float) -> Vector:
        return qt.advance(x, self.saturate(u), dt, self.plant_params())

    def output(self, x: Sequence[float]) -> Vector:
        kc = self.plant_params().kc
        return tuple(kc * h for h in x)

    def jacobians(self, x0: Sequence[float], u0: Sequence[float]) -> tuple[Any, Any, Any]:
        """core.analysis.linearize's matrices (bit for bit); a level inside the last
        film of water (core.plant.H_FILM), where that refuses, follows the blend."""
        from quadtank_tui.core.analysis import linearize as linearize_levels  # loads python-control

        p = self.plant_params()
        if min(x0) >= qt.H_FILM:
            m = linearize_levels(p, x0)
            return m.A, m.B, [[p.kc if j == i else 0.0 for j in range(4)] for i in range(4)]
        # a level at or below 0 takes the slope at 0 (the outflow law is one-sided)
        d = [orifice_slope(max(x0[i], 0.0), p.outlet(i), p.g, qt.H_FILM) / p.area(i) for i in range(4)]
        A = [[-d[0], 0.0, d[2] * p.A3 / p.A1, 0.0],
             [0.0, -d[1], 0.0, d[3] * p.A4 / p.A2],
             [0.0, 0.0, -d[2], 0.0],
             [0.0, 0.0, 0.0, -d[3]]]
        B = [[p.gamma1 * p.k1 / p.A1, 0.0], [0.0, p.gamma2 * p.k2 / p.A2],
             [0.0, (1 - p.gamma2) * p.k2 / p.A3], [(1 - p.gamma1) * p.k1 / p.A4, 0.0]]
        C = [[p.kc if j == i else 0.0 for j in range(4)] for i in range(4)]
        return A, B, C

    def steady_state(self, u: Sequence[float]) -> Vector:
        return qt.steady_state_levels(self.saturate(u), self.plant_params())

    def steady_inputs(self, levels: Sequence[float | None]) -> OperatingPoint:
        """The lower levels (h1, h2) set, the upper ones follow (None or omitted)."""
        if len(levels) not in (2, 4) or levels[0] is None or levels[1] is None or any(
                v is not None for v in levels[2:]):
            raise SteadyStateError("give the lower levels (h1, h2); the upper levels follow from them")
        try:
            op = qt.steady_state_inputs(float(levels[0]), float(levels[1]), self.plant_params())
        except qt.SteadyStateError as exc:
            raise SteadyStateError(str(exc)) from None
        if max(op.v) > self.pump_max:
            raise SteadyStateError(f"levels ({levels[0]:g}, {levels[1]:g}) cm need pump voltages "
                                   f"({op.v[0]:.3g}, {op.v[1]:.3g}) V, above the pumps' {self.pump_max:g} V")
        return OperatingPoint(tuple(op.h), tuple(op.v))


@dataclass(frozen=True)
class QuadTank(_FourTanks):
    """Johansson's quadruple tank (Lund), constants as core.plant.PlantParams."""

    params: PlantParams = PlantParams()

    kind = "quadtank"
    title = "quadruple tank (Johansson)"
    outlet_names = ("a1", "a2", "a3", "a4")
    valve_names = ("gamma1", "gamma2")

    def area(self, i: int) -> float:
        return self.params.area(i)

    def plant_params(self) -> PlantParams:
        return self.params

    def values(self) -> dict[str, float]:
        return {f.name: getattr(self.params, f.name) for f in fields(self.params)}

    def with_values(self, **changes: float) -> Plant:
        unknown = sorted(set(changes) - set(self.values()))
        if unknown:
            raise PlantError(f"{self.kind} has no constant {', '.join(unknown)}")
        return QuadTank(replace(self.params, **changes))


@dataclass(frozen=True)
class DesautelQTP(_FourTanks):
    """Quanser's quadruple tank in Desautel's parameterization; defaults: his Table 9.

    alpha_i : orifice coefficients (a_i / A_i), dimensionless
    beta_i : pump coefficients into tank i, cm/(V s)
    g : cm/s^2; hmax : tank height, cm (Quanser tanks: 30 cm)
    kc : sensor gain, V/cm.  Desautel gives none for the QTP (his states are cm); the
        default maps the 30 cm tank onto the program's 10 V input range.
    vmax : pump amplifier range, V (0..22 V, as his CTP's)
    """

    alpha1: float = 0.010949
    alpha2: float = 0.012142
    alpha3: float = 0.0040214
    alpha4: float = 0.0053157
    beta1: float = 0.21009
    beta2: float = 0.23525
    beta3: float = 0.079938
    beta4: float = 0.088820
    g: float = 981.0
    hmax: float = 30.0
    kc: float = 1.0 / 3.0
    vmax: float = 22.0

    kind = "desautel-qtp"
    title = "quadruple tank (Quanser, Desautel)"
    units: ClassVar[dict[str, str]] = {
        **{f"alpha{i}": "a/A" for i in range(1, 5)}, **{f"beta{i}": "cm/(V s)" for i in range(1, 5)},
        "g": "cm/s²", "hmax": "cm", "kc": "V/cm", "vmax": "V"}
    outlet_names = ("alpha1", "alpha2", "alpha3", "alpha4")

    def __post_init__(self) -> None:
        if not self.vmax > 0:
            raise PlantError(f"vmax must be > 0 V, got {self.vmax}")
        for name in ("beta1", "beta2", "beta3", "beta4"):
            if getattr(self, name) < 0:
                raise PlantError(f"{name} must be >= 0, got {getattr(self, name)}")
        self.plant_params()  # validates the rest

    @property
    def pump_max(self) -> float:
        return self.vmax

    @property
    def inputs(self) -> tuple[Signal, ...]:
        return (Signal("v1", "V", 0.0, self.vmax, self.vmax), Signal("v2", "V", 0.0, self.vmax, self.vmax))

    def plant_params(self) -> PlantParams:
        k1, k2 = self.beta1 + self.beta4, self.beta2 + self.beta3
        if k1 <= 0 or k2 <= 0:
            raise PlantError("each pump needs a positive coefficient into one of its tanks")
        for i, name in enumerate(("alpha1", "alpha2", "alpha3", "alpha4")):
            if not 0.0 < getattr(self, name) < 1.0:  # a_i < A_i
                raise PlantError(f"{name} must be in (0, 1), got {getattr(self, name)}")
        return PlantParams(
            A1=1.0, A2=1.0, A3=1.0, A4=1.0,
            a1=self.alpha1, a2=self.alpha2, a3=self.alpha3, a4=self.alpha4,
            k1=k1, k2=k2, gamma1=self.beta1 / k1, gamma2=self.beta2 / k2,
            kc=self.kc, g=self.g, hmax=self.hmax,
        )
