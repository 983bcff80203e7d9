"""The quadruple tank through the plant interface: Johansson's rig, and Desautel's.

:class:`QuadTank` presents core.plants.johansson unchanged: every method
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

from quadtank_tui.core.plants import johansson as qt
from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError
from quadtank_tui.core.plants.johansson import PlantParams
from quadtank_tui.core.plants import effects as fx
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
#: The real-rig effects of a four-tank plant (off at 0; core.plants.effects):
#: spill3/spill4 the fraction of upper tank 3's/4's overflow that falls into the
#: lower tank 1/2 below it (a lower tank's overflow leaves the process), vmin1/vmin2
#: the pump thresholds, V, ysat1..ysat4 the sensor ranges, V, lam1..lam4 a laminar
#: term of each outlet (q = a sqrt(2 g h) + lam h; cm^2/s, in the QTP's level units
#: cm/s per cm), off1..off4 each sensor's offset, V (it reads kc h + off).
FOUR_TANK_EFFECTS = ("spill3", "spill4", "vmin1", "vmin2", "ysat1", "ysat2", "ysat3", "ysat4",
                     "lam1", "lam2", "lam3", "lam4", "off1", "off2", "off3", "off4")
FOUR_TANK_EFFECT_UNITS = {"spill3": "fraction", "spill4": "fraction", "vmin1": "V", "vmin2": "V",
                          **{f"ysat{i}": "V" for i in range(1, 5)},
                          **{f"lam{i}": "cm²/s laminar" for i in range(1, 5)},
                          **{f"off{i}": "V offset" for i in range(1, 5)}}
_LAM = ("lam1", "lam2", "lam3", "lam4")
_OFF = ("off1", "off2", "off3", "off4")


@dataclass(frozen=True, kw_only=True)
class _FourTankEffects:
    """The effects' constants (keyword-only: QuadTank(params) stays as it was)."""

    spill3: float = 0.0
    spill4: float = 0.0
    vmin1: float = 0.0
    vmin2: float = 0.0
    ysat1: float = 0.0
    ysat2: float = 0.0
    ysat3: float = 0.0
    ysat4: float = 0.0
    lam1: float = 0.0
    lam2: float = 0.0
    lam3: float = 0.0
    lam4: float = 0.0
    off1: float = 0.0
    off2: float = 0.0
    off3: float = 0.0
    off4: float = 0.0


class _FourTanks(_FourTankEffects, Plant):
    """What both parameterizations share: the model is core.plants.johansson's, and with an
    effect on, that model with the effect (the plain model runs while all are off)."""

    effect_names = FOUR_TANK_EFFECTS

    def values(self) -> dict[str, float]:
        """The constants in the class's order, the effects last."""
        every = super().values()
        return {**{k: v for k, v in every.items() if k not in FOUR_TANK_EFFECTS},
                **{k: every[k] for k in FOUR_TANK_EFFECTS}}

    def plant_params(self) -> PlantParams:
        raise NotImplementedError

    def _check_effects(self) -> None:
        fx.check_effects(self, ("spill3", "spill4"), ("vmin1", "vmin2"), self.pump_max,
                         ("ysat1", "ysat2", "ysat3", "ysat4"))
        fx.check_laminar(self, _LAM)
        fx.check_offsets(self, _OFF, FULL_SCALE_V)

    def _lam(self) -> tuple[float, float, float, float]:
        return (self.lam1, self.lam2, self.lam3, self.lam4)

    def _outflow(self, h: float, i: int, p: PlantParams) -> float:
        """Outlet i's flow, cm^3/s: Torricelli's, plus the laminar term when it is on."""
        lam = self._lam()[i]
        q = qt.outflow(h, p.outlet(i), p.g)
        return q + lam * max(h, 0.0) if lam != 0.0 else q

    def _head(self, q: float, i: int, p: PlantParams) -> float:
        """The level at which outlet i passes q cm^3/s."""
        lam = self._lam()[i]
        if lam == 0.0:
            return qt.level_for_outflow(q, p.outlet(i), p.g)
        return fx.head_for_laminar_flow(q, p.outlet(i), p.g, lam)

    @property
    def effects_on(self) -> bool:
        """Whether any real-rig effect is on (else the plain model runs, bit for bit)."""
        return fx.any_on(self, FOUR_TANK_EFFECTS)

    def _rhs_effects(self, x: Sequence[float], u: Sequence[float]) -> Vector:
        """johansson.rhs with the pump thresholds and the upper tanks' overflow
        falling (in the fractions spill3, spill4) into the tanks below them."""
        p = self.plant_params()
        v1 = fx.pump_volts(max(float(u[0]), 0.0), self.vmin1)
        v2 = fx.pump_volts(max(float(u[1]), 0.0), self.vmin2)
        q = [self._outflow(x[i], i, p) for i in range(4)]
        f3 = -q[2] + (1.0 - p.gamma2) * p.k2 * v2  # cm^3/s
        f4 = -q[3] + (1.0 - p.gamma1) * p.k1 * v1
        f1 = -q[0] + q[2] + p.gamma1 * p.k1 * v1
        f2 = -q[1] + q[3] + p.gamma2 * p.k2 * v2
        if x[2] >= p.hmax and f3 > 0.0:
            f1, f3 = f1 + self.spill3 * f3, 0.0
        if x[3] >= p.hmax and f4 > 0.0:
            f2, f4 = f2 + self.spill4 * f4, 0.0
        if x[0] >= p.hmax and f1 > 0.0:
            f1 = 0.0
        if x[1] >= p.hmax and f2 > 0.0:
            f2 = 0.0
        return (f1 / p.A1, f2 / p.A2, f3 / p.A3, f4 / p.A4)

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
        ranges = (self.ysat1, self.ysat2, self.ysat3, self.ysat4)
        return tuple(Signal(f"y{i + 1}", "V", 0.0, fx.sensor_top(p.kc * p.hmax, ranges[i])) for i in range(4))

    def layout(self) -> Layout:
        tanks = (TankView("1", 0, 0, 0), TankView("2", 1, 1, 0), TankView("3", 2, 0, 1), TankView("4", 3, 1, 1))
        pumps = (PumpView("pump 1", 0, ((0, "gamma1"), (3, "1 - gamma1"))),
                 PumpView("pump 2", 1, ((1, "gamma2"), (2, "1 - gamma2"))))
        pipes = (PipeView(2, 0, "a3"), PipeView(3, 1, "a4"), PipeView(0, None, "a1"), PipeView(1, None, "a2"))
        return Layout(tanks, pumps, pipes)

    def rhs(self, x: Sequence[float], u: Sequence[float]) -> Vector:
        if self.effects_on:
            return self._rhs_effects(x, u)
        return qt.rhs(x, u, self.plant_params())

    def advance(self, x: Sequence[float], u: Sequence[float], dt: float) -> Vector:
        if self.effects_on:  # the same Dormand-Prince step and tolerance, over the rhs with effects
            return Plant.advance(self, x, u, dt)
        return qt.advance(x, self.saturate(u), dt, self.plant_params())

    def output(self, x: Sequence[float]) -> Vector:
        kc = self.plant_params().kc
        if self.effects_on:
            ranges = (self.ysat1, self.ysat2, self.ysat3, self.ysat4)
            offsets = (self.off1, self.off2, self.off3, self.off4)
            return tuple(fx.reading(kc * h, o, r) for h, o, r in zip(x, offsets, ranges))
        return tuple(kc * h for h in x)

    def jacobians(self, x0: Sequence[float], u0: Sequence[float]) -> tuple[Any, Any, Any]:
        """core.analysis.linearize's matrices (bit for bit); a level inside the last
        film of water (johansson.H_FILM), where that refuses, follows the blend; a
        laminar term adds its slope lam_i / A_i to each outlet's."""
        A, B, C = self._torricelli_jacobians(x0, u0)
        lam = self._lam()
        if not any(lam):
            return A, B, C
        p = self.plant_params()
        A = [[float(v) for v in row] for row in A]
        for i in range(4):
            A[i][i] -= lam[i] / p.area(i)
        A[0][2] += lam[2] / p.A1
        A[1][3] += lam[3] / p.A2
        return A, B, C

    def _torricelli_jacobians(self, x0: Sequence[float], u0: Sequence[float]) -> tuple[Any, Any, Any]:
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
        if not self.effects_on:
            return qt.steady_state_levels(self.saturate(u), self.plant_params())
        p = self.plant_params()
        v = self.saturate(u)
        v1, v2 = fx.pump_volts(v[0], self.vmin1), fx.pump_volts(v[1], self.vmin2)
        h = [0.0, 0.0, 0.0, 0.0]
        ins = {2: (1 - p.gamma2) * p.k2 * v2, 3: (1 - p.gamma1) * p.k1 * v1}
        for i in (2, 3):
            h[i] = min(self._head(ins[i], i, p), p.hmax)
        # an upper tank at its brim passes its outflow and spills the rest, of which
        # spill3 (spill4) reaches the tank below
        extra = [0.0, 0.0]
        for upper, lower, share in ((2, 0, self.spill3), (3, 1, self.spill4)):
            if h[upper] >= p.hmax:
                extra[lower] = share * max(ins[upper] - self._outflow(p.hmax, upper, p), 0.0)
        for i, inflow in ((0, p.gamma1 * p.k1 * v1 + self._outflow(h[2], 2, p)),
                          (1, p.gamma2 * p.k2 * v2 + self._outflow(h[3], 3, p))):
            h[i] = min(self._head(inflow + extra[i] if extra[i] > 0.0 else inflow, i, p), p.hmax)
        return (h[0], h[1], h[2], h[3])

    def steady_inputs(self, levels: Sequence[float | None]) -> OperatingPoint:
        """The lower levels (h1, h2) set, the upper ones follow (None or omitted)."""
        if len(levels) not in (2, 4) or levels[0] is None or levels[1] is None or any(
                v is not None for v in levels[2:]):
            raise SteadyStateError("give the lower levels (h1, h2); the upper levels follow from them")
        if any(self._lam()):
            op = self._laminar_steady_inputs(float(levels[0]), float(levels[1]))
        else:
            op = qt.steady_state_inputs(float(levels[0]), float(levels[1]), self.plant_params())
        v = tuple(op.u)
        if self.effects_on:  # a pump below its threshold moves nothing: what it needs comes on top
            v = tuple(x + t if x > 0.0 else x for x, t in zip(v, (self.vmin1, self.vmin2)))
        if max(v) > self.pump_max:
            raise SteadyStateError(f"levels ({levels[0]:g}, {levels[1]:g}) cm need pump voltages "
                                   f"({v[0]:.3g}, {v[1]:.3g}) V, above the pumps' {self.pump_max:g} V")
        return OperatingPoint(tuple(op.x), v)


    def _laminar_steady_inputs(self, h1: float, h2: float) -> OperatingPoint:
        """johansson.steady_state_inputs with the laminar outflow: M v = (q1(h1), q2(h2))."""
        p = self.plant_params()
        if h1 < 0 or h2 < 0:
            raise SteadyStateError(f"levels must be >= 0 cm, got ({h1}, {h2})")
        m11, m12 = p.gamma1 * p.k1, (1 - p.gamma2) * p.k2
        m21, m22 = (1 - p.gamma1) * p.k1, p.gamma2 * p.k2
        det = m11 * m22 - m12 * m21
        if abs(det) <= 1e-12 * max(abs(m11 * m22), abs(m12 * m21), 1e-300):
            raise SteadyStateError("gamma1 + gamma2 = 1: the lower-tank flows are tied together, so the "
                                   "levels cannot be set independently (no unique steady-state input)")
        q1, q2 = self._outflow(h1, 0, p), self._outflow(h2, 1, p)
        v1, v2 = (m22 * q1 - m12 * q2) / det, (-m21 * q1 + m11 * q2) / det
        if v1 < -1e-12 or v2 < -1e-12:
            raise SteadyStateError(f"levels ({h1:g}, {h2:g}) cm need pump voltages ({v1:.3g}, {v2:.3g}) V; "
                                   "a pump cannot run backwards")
        v1, v2 = max(v1, 0.0), max(v2, 0.0)
        h3 = self._head((1 - p.gamma2) * p.k2 * v2, 2, p)
        h4 = self._head((1 - p.gamma1) * p.k1 * v1, 3, p)
        if h3 >= p.hmax or h4 >= p.hmax:
            raise SteadyStateError(f"levels ({h1:g}, {h2:g}) cm would overflow an upper tank")
        return OperatingPoint((h1, h2, h3, h4), (v1, v2))


@dataclass(frozen=True)
class QuadTank(_FourTanks):
    """Johansson's quadruple tank (Lund), constants as johansson.PlantParams, and
    the real-rig effects (:data:`FOUR_TANK_EFFECTS`, off at 0: then every method is
    core.plants.johansson's, bit for bit)."""

    params: PlantParams = PlantParams()

    kind = "quadtank"
    title = "quadruple tank (Johansson)"
    outlet_names = ("a1", "a2", "a3", "a4")
    valve_names = ("gamma1", "gamma2")

    def __post_init__(self) -> None:
        self._check_effects()

    def area(self, i: int) -> float:
        return self.params.area(i)

    def plant_params(self) -> PlantParams:
        return self.params

    def values(self) -> dict[str, float]:
        """The SIMULATION section's constants, then the effects (a `.par` file's
        PLANT section holds those, files.par)."""
        return {**{f.name: getattr(self.params, f.name) for f in fields(self.params)},
                **{n: getattr(self, n) for n in FOUR_TANK_EFFECTS}}

    def effects(self) -> dict[str, float]:
        """The effects that are on, by name."""
        return {n: getattr(self, n) for n in FOUR_TANK_EFFECTS if getattr(self, n) != 0.0}

    def with_values(self, **changes: float) -> Plant:
        unknown = sorted(set(changes) - set(self.values()))
        if unknown:
            raise PlantError(f"{self.kind} has no constant {', '.join(unknown)}")
        effects = {k: v for k, v in changes.items() if k in FOUR_TANK_EFFECTS}
        constants = {k: v for k, v in changes.items() if k not in FOUR_TANK_EFFECTS}
        return replace(self, params=replace(self.params, **constants) if constants else self.params, **effects)


@dataclass(frozen=True)
class DesautelQTP(_FourTanks):
    """Quanser's quadruple tank in Desautel's parameterization; defaults: his Table 9.

    alpha_i : orifice coefficients (a_i / A_i), dimensionless
    beta_i : pump coefficients into tank i, cm/(V s)
    g : cm/s^2; hmax : tank height, cm (Quanser tanks: 30 cm)
    kc : sensor gain, V/cm.  Desautel gives none for the QTP (his states are cm); the
        default maps the 30 cm tank onto the program's 10 V input range.
    vmax : pump amplifier range, V (0..22 V, as his CTP's)
    spill3, spill4, vmin1, vmin2, ysat1..ysat4 : the real-rig effects, off at 0
        (see :data:`FOUR_TANK_EFFECTS`)
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
        "g": "cm/s²", "hmax": "cm", "kc": "V/cm", "vmax": "V", **FOUR_TANK_EFFECT_UNITS}
    outlet_names = ("alpha1", "alpha2", "alpha3", "alpha4")

    def __post_init__(self) -> None:
        if not self.vmax > 0:
            raise PlantError(f"vmax must be > 0 V, got {self.vmax}")
        for name in ("beta1", "beta2", "beta3", "beta4"):
            if getattr(self, name) < 0:
                raise PlantError(f"{name} must be >= 0, got {getattr(self, name)}")
        self.plant_params()  # validates the rest
        self._check_effects()

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
