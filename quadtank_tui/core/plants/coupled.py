"""Two coupled tanks: Quanser's cascade (Desautel's CTP) and Murray-Smith's two-input rig.

Cascade (001_..., 2.1.2): one pump into the upper tank 1, which drains into the
lower tank 2, which drains into the basin; levels in cm, pump in V::

    x1' = beta1 u - alpha1 sqrt(2 g x1)
    x2' = alpha1 sqrt(2 g x1) - alpha2 sqrt(2 g x2)

Two inputs (004_..., equations 1-2): two tanks side by side joined by an orifice
near the base, a pump into each, tank 2 draining at height H3; levels in m, flows
in m^3/s, pumps Q = Gp v, sensors y = Gd H::

    A1 H1' = Qi1 - Cd1 a1 sqrt(2 g (H1 - H2))
    A2 H2' = Qi2 + Cd1 a1 sqrt(2 g (H1 - H2)) - Cd2 a2 sqrt(2 g (H2 - H3))

written for H1 > H2; when H2 rises above H1 the orifice flow reverses (the signed
law below), and below H3 the drain carries nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

from quadtank_tui.core.plants.common import PlantError
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
    head_for_flow,
    orifice_flow,
    orifice_slope,
)

#: Head below which Torricelli's law is blended to 0: 0.05 mm, as johansson.H_FILM.
FILM_CM = 0.005
FILM_M = 0.005e-2


def _positive(obj: object, names: Sequence[str]) -> None:
    for name in names:
        value = getattr(obj, name)
        if not isinstance(value, (int, float)) or not value > 0 or value == float("inf"):
            raise PlantError(f"{name} must be a finite number > 0, got {value!r}")


def _spill(f: float, x: float, hmax: float) -> float:
    """A full tank rises no further: what would raise it leaves the process."""
    return 0.0 if x >= hmax and f > 0.0 else f


@dataclass(frozen=True)
class CoupledCascade(Plant):
    """Quanser coupled tanks, one pump (Desautel's CTP); defaults from his thesis.

    alpha1, alpha2 : orifice coefficients of the upper and lower tank (his Table 1
        calibration with the medium orifices, section 2.3)
    beta1 : pump coefficient, cm/(V s)
    g : cm/s^2; hmax : tank height, cm
    kc1, kc2 : sensor gains, V/cm: the inverse of his calibrated sensor gains
        g1 = 5.4310, g2 = 5.5558 cm/V (2.3; his offsets b1, b2 are left to the DAQ map)
    vmax : pump amplifier range, V (3.2.1: 0 to 22 V)

    What a real rig's logs show, each off at its default (0), so the published
    figures stay as they are (a physical fit can free them, core.identify.physical):

    spill1 : fraction of the upper tank's overflow that falls into the lower tank
        (the rest leaves the process), [0, 1]
    vmin : pump threshold, V: below it the pump moves no water, above it
        beta1 (u - vmin)
    ysat1, ysat2 : sensor ranges, V: a reading saturates there (0: the sensor
        covers the whole tank)
    lam1, lam2 : a laminar term of each outlet, 1/s: q = alpha sqrt(2 g h) + lam h
        (cm/s of level, as every flow here)
    area1 : tank 1's cross-section relative to tank 2's (0: the same, as on
        Desautel's rig): tank 1's level moves by its net flow / area1, and it spills
        at hmax of its own height
    off1, off2 : sensor offsets, V: a sensor reads kc h + off
    """

    alpha1: float = 0.0097909
    alpha2: float = 0.0098811
    beta1: float = 0.24813
    g: float = 981.0
    hmax: float = 30.0
    kc1: float = 1.0 / 5.4310
    kc2: float = 1.0 / 5.5558
    vmax: float = 22.0
    spill1: float = 0.0
    vmin: float = 0.0
    ysat1: float = 0.0
    ysat2: float = 0.0
    lam1: float = 0.0
    lam2: float = 0.0
    area1: float = 0.0
    off1: float = 0.0
    off2: float = 0.0

    kind = "coupled-cascade"
    title = "coupled tanks, cascade (Quanser, Desautel)"
    units: ClassVar[dict[str, str]] = {
        "alpha1": "orifice coef.", "alpha2": "orifice coef.", "beta1": "cm/(V s)", "g": "cm/s²",
        "hmax": "cm", "kc1": "V/cm", "kc2": "V/cm", "vmax": "V", "spill1": "fraction", "vmin": "V",
        "ysat1": "V", "ysat2": "V", "lam1": "1/s laminar", "lam2": "1/s laminar", "area1": "x tank 2's",
        "off1": "V offset", "off2": "V offset"}
    outlet_names = ("alpha1", "alpha2")
    effect_names = ("spill1", "vmin", "ysat1", "ysat2", "lam1", "lam2", "area1", "off1", "off2")
    #: The loop controls the lower tank (Desautel: c = [0 1]).
    controlled: ClassVar[tuple[int, ...]] = (1,)

    def __post_init__(self) -> None:
        _positive(self, ("alpha1", "alpha2", "beta1", "g", "hmax", "kc1", "kc2", "vmax"))
        # vmin checked as >= 0 here and against vmax below, in this plant's own words
        fx.check_effects(self, ("spill1",), (), self.vmax, ("vmin", "ysat1", "ysat2"))
        if self.vmin >= self.vmax:
            raise PlantError(f"vmin must be below vmax = {self.vmax:g} V, got {self.vmin!r}")
        fx.check_laminar(self, ("lam1", "lam2", "area1"))
        fx.check_offsets(self, ("off1", "off2"), 10.0)

    @property
    def ratio1(self) -> float:
        """Tank 1's cross-section over tank 2's (area1, 1 when off)."""
        return self.area1 if self.area1 > 0.0 else 1.0
    @property
    def states(self) -> tuple[Signal, ...]:
        return (Signal("x1", "cm", 0.0, self.hmax, self.hmax), Signal("x2", "cm", 0.0, self.hmax, self.hmax))

    @property
    def inputs(self) -> tuple[Signal, ...]:
        return (Signal("u", "V", 0.0, self.vmax, self.vmax),)

    @property
    def outputs(self) -> tuple[Signal, ...]:
        return (Signal("y1", "V", 0.0, fx.sensor_top(self.kc1 * self.hmax, self.ysat1)),
                Signal("y2", "V", 0.0, fx.sensor_top(self.kc2 * self.hmax, self.ysat2)))

    def layout(self) -> Layout:
        return Layout(
            tanks=(TankView("1", 0, 0, 1), TankView("2", 1, 0, 0)),
            pumps=(PumpView("pump", 0, ((0, "1"),)),),
            pipes=(PipeView(0, 1, "alpha1"), PipeView(1, None, "alpha2")),
        )

    def _q(self, x: float, alpha: float, lam: float = 0.0) -> float:
        q = orifice_flow(max(x, 0.0), alpha, self.g, FILM_CM)
        return q + lam * max(x, 0.0) if lam != 0.0 else q

    def _head(self, q: float, alpha: float, lam: float) -> float:
        """The level at which an outlet passes q (cm/s of level)."""
        if lam == 0.0:
            return head_for_flow(q, alpha, self.g, FILM_CM)
        return fx.head_for_laminar_flow(q, alpha, self.g, lam)

    def _pump(self, u: float) -> float:
        """Pump flow (cm/s of level in tank 1) at u V: beta1 u, less the threshold."""
        return self.beta1 * fx.pump_volts(min(max(u, 0.0), self.vmax), self.vmin)

    def rhs(self, x: Sequence[float], u: Sequence[float]) -> Vector:
        q1, q2 = self._q(x[0], self.alpha1, self.lam1), self._q(x[1], self.alpha2, self.lam2)
        f1 = self._pump(u[0]) - q1
        f2 = q1 - q2
        if self.spill1 > 0.0 and x[0] >= self.hmax and f1 > 0.0:
            f2 += self.spill1 * f1  # flows in cm/s of tank 2's level
        f1 = _spill(f1, x[0], self.hmax)
        return (f1 / self.area1 if self.area1 > 0.0 else f1, _spill(f2, x[1], self.hmax))

    def output(self, x: Sequence[float]) -> Vector:
        return (fx.reading(self.kc1 * x[0], self.off1, self.ysat1), fx.reading(self.kc2 * x[1], self.off2, self.ysat2))

    def jacobians(self, x0: Sequence[float], u0: Sequence[float]) -> tuple[Any, Any, Any]:
        """Desautel (2.1.13): A = [[-l1, 0], [l1, -l2]], l_i = alpha_i sqrt(g / (2 x_i))
        (+ lam_i with a laminar term; tank 1's row over area1)."""
        l1 = orifice_slope(x0[0], self.alpha1, self.g, FILM_CM) + self.lam1
        l2 = orifice_slope(x0[1], self.alpha2, self.g, FILM_CM) + self.lam2
        r = self.ratio1
        if r == 1.0:
            return [[-l1, 0.0], [l1, -l2]], [[self.beta1], [0.0]], [[self.kc1, 0.0], [0.0, self.kc2]]
        return [[-l1 / r, 0.0], [l1, -l2]], [[self.beta1 / r], [0.0]], [[self.kc1, 0.0], [0.0, self.kc2]]

    def steady_state(self, u: Sequence[float]) -> Vector:
        (v,) = self.saturate(u)
        q = self._pump(v)
        x1 = min(self._head(q, self.alpha1, self.lam1), self.hmax)
        into2 = self._q(x1, self.alpha1, self.lam1)
        if self.spill1 > 0.0 and x1 >= self.hmax:
            into2 += self.spill1 * max(q - into2, 0.0)
        x2 = min(self._head(into2, self.alpha2, self.lam2), self.hmax)
        return (x1, x2)

    def steady_inputs(self, levels: Sequence[float | None]) -> OperatingPoint:
        """One pump sets one level: give x1 (Desautel's choice, 2.1.5) or x2, not both.
        u = alpha1 sqrt(2 g x1) / beta1 and x2 = alpha1^2 x1 / alpha2^2 (2.1.6)."""
        if len(levels) != 2 or (levels[0] is None) == (levels[1] is None):
            raise SteadyStateError("one pump sets one level: give x1 or x2 (the other follows)")
        if levels[0] is not None:
            x1 = float(levels[0])
            _check_level("x1", x1, self.hmax)
            q = self._q(x1, self.alpha1, self.lam1)
            x2 = self._head(q, self.alpha2, self.lam2)
        else:
            x2 = float(levels[1])  # type: ignore[arg-type]  # not None: exactly one level is given (checked above)
            _check_level("x2", x2, self.hmax)
            q = self._q(x2, self.alpha2, self.lam2)
            x1 = self._head(q, self.alpha1, self.lam1)
        u = q / self.beta1 + (self.vmin if q > 0.0 else 0.0)
        if x1 > self.hmax or x2 > self.hmax:
            raise SteadyStateError(f"levels ({x1:.3g}, {x2:.3g}) cm: a tank would overflow ({self.hmax:g} cm)")
        if u > self.vmax:
            raise SteadyStateError(f"the pump would need {u:.3g} V, above its {self.vmax:g} V")
        return OperatingPoint((x1, x2), (u,))


def _check_level(name: str, x: float, hmax: float) -> None:
    if not 0.0 <= x <= hmax:
        raise SteadyStateError(f"{name} must be in [0, {hmax:g}], got {x:g}")


@dataclass(frozen=True)
class CoupledTITO(Plant):
    """Murray-Smith's two-input two-output coupled tanks (SI units); defaults: his
    parameter list (section 2)."""

    A1: float = 9.7e-3
    A2: float = 9.7e-3
    a1: float = 3.956e-5
    a2: float = 3.85e-5
    Cd1: float = 0.63
    Cd2: float = 0.58
    H3: float = 0.03
    g: float = 9.81
    Gp: float = 7.2e-6
    Gd: float = 33.33
    hmax: float = 0.3
    qmax: float = 5e-5
    spill1: float = 0.0
    spill2: float = 0.0
    vmin1: float = 0.0
    vmin2: float = 0.0
    ysat1: float = 0.0
    ysat2: float = 0.0

    kind = "coupled-tito"
    title = "coupled tanks, two inputs (Murray-Smith)"
    units: ClassVar[dict[str, str]] = {
        "A1": "m²", "A2": "m²", "a1": "m² orifice", "a2": "m² drain", "Cd1": "discharge coef.",
        "Cd2": "discharge coef.", "H3": "m, drain height", "g": "m/s²", "Gp": "m³/(s V)", "Gd": "V/m",
        "hmax": "m", "qmax": "m³/s", "spill1": "fraction", "spill2": "fraction", "vmin1": "V", "vmin2": "V",
        "ysat1": "V", "ysat2": "V"}
    controlled: ClassVar[tuple[int, ...]] = (0, 1)
    #: Tank 1 empties through the orifice into tank 2, tank 2 through the drain.
    outlet_names = ("a1", "a2")
    #: What a real rig's logs show, off at 0 (core.plants.effects): spill1 (spill2)
    #: the fraction of tank 1's (2's) overflow that falls over the wall into the
    #: other tank, vmin1/vmin2 the pump thresholds, ysat1/ysat2 the sensor ranges, V.
    effect_names = ("spill1", "spill2", "vmin1", "vmin2", "ysat1", "ysat2")

    def area(self, i: int) -> float:
        return (self.A1, self.A2)[i]

    def __post_init__(self) -> None:
        _positive(self, ("A1", "A2", "a1", "a2", "Cd1", "Cd2", "g", "Gp", "Gd", "hmax", "qmax"))
        if not 0.0 <= self.H3 < self.hmax:
            raise PlantError(f"H3 must be in [0, hmax), got {self.H3}")
        for a, area in (("a1", "A1"), ("a2", "A2")):
            if getattr(self, a) >= getattr(self, area):
                raise PlantError(f"{a} must be smaller than the tank's cross-section {area} = {getattr(self, area):g}")
        fx.check_effects(self, ("spill1", "spill2"), ("vmin1", "vmin2"), self.vmax, ("ysat1", "ysat2"))

    @property
    def effects_on(self) -> bool:
        """Whether a real-rig effect is on (else the plain model runs, bit for bit)."""
        return fx.any_on(self, self.effect_names)

    def _inflows(self, u: Sequence[float]) -> tuple[float, float]:
        """Pump flows, m^3/s: Gp v within the range, less the thresholds."""
        vmax = self.vmax
        v1, v2 = min(max(u[0], 0.0), vmax), min(max(u[1], 0.0), vmax)
        return self.Gp * fx.pump_volts(v1, self.vmin1), self.Gp * fx.pump_volts(v2, self.vmin2)

    @property
    def vmax(self) -> float:
        """Pump voltage of the largest inflow, V (5e-5 m^3/s at Gp: 6.94 V)."""
        return self.qmax / self.Gp

    @property
    def states(self) -> tuple[Signal, ...]:
        return (Signal("H1", "m", 0.0, self.hmax, self.hmax), Signal("H2", "m", 0.0, self.hmax, self.hmax))

    @property
    def inputs(self) -> tuple[Signal, ...]:
        return (Signal("v1", "V", 0.0, self.vmax), Signal("v2", "V", 0.0, self.vmax))

    @property
    def outputs(self) -> tuple[Signal, ...]:
        top = self.Gd * self.hmax
        return (Signal("y1", "V", 0.0, fx.sensor_top(top, self.ysat1)),
                Signal("y2", "V", 0.0, fx.sensor_top(top, self.ysat2)))

    def layout(self) -> Layout:
        return Layout(
            tanks=(TankView("1", 0, 0, 0), TankView("2", 1, 1, 0)),
            pumps=(PumpView("pump 1", 0, ((0, "1"),)), PumpView("pump 2", 1, ((1, "1"),))),
            pipes=(PipeView(0, 1, "a1", two_way=True), PipeView(1, None, "a2 (drain at H3)")),
        )

    def flows(self, x: Sequence[float]) -> tuple[float, float]:
        """(tank 1 -> tank 2 through the orifice, negative when reversed; drain), m^3/s."""
        q12 = orifice_flow(x[0] - x[1], self.Cd1 * self.a1, self.g, FILM_M)
        q2 = orifice_flow(max(x[1] - self.H3, 0.0), self.Cd2 * self.a2, self.g, FILM_M)
        return q12, q2

    def rhs(self, x: Sequence[float], u: Sequence[float]) -> Vector:
        if self.effects_on:
            return self._rhs_effects(x, u)
        vmax = self.vmax
        q1 = self.Gp * min(max(u[0], 0.0), vmax)
        q2in = self.Gp * min(max(u[1], 0.0), vmax)
        q12, q2 = self.flows(x)
        return (_spill((q1 - q12) / self.A1, x[0], self.hmax),
                _spill((q2in + q12 - q2) / self.A2, x[1], self.hmax))

    def _rhs_effects(self, x: Sequence[float], u: Sequence[float]) -> Vector:
        """The model with thresholds, and a full tank's excess (m^3/s) falling in the
        fractions spill1, spill2 into the other tank (if that one is full too, it leaves)."""
        q1, q2in = self._inflows(u)
        q12, q2 = self.flows(x)
        f1, f2 = q1 - q12, q2in + q12 - q2
        over1 = f1 if x[0] >= self.hmax and f1 > 0.0 else 0.0
        over2 = f2 if x[1] >= self.hmax and f2 > 0.0 else 0.0
        f1, f2 = f1 - over1 + self.spill2 * over2, f2 - over2 + self.spill1 * over1
        return (_spill(f1 / self.A1, x[0], self.hmax), _spill(f2 / self.A2, x[1], self.hmax))

    def output(self, x: Sequence[float]) -> Vector:
        if self.effects_on:
            return (fx.sensor(self.Gd * x[0], self.ysat1), fx.sensor(self.Gd * x[1], self.ysat2))
        return (self.Gd * x[0], self.Gd * x[1])

    def jacobians(self, x0: Sequence[float], u0: Sequence[float]) -> tuple[Any, Any, Any]:
        """Murray-Smith (11): alpha1 = Cd1 a1 / 2 sqrt(2 g / (H1 - H2)) (12) and
        alpha2 = Cd2 a2 / 2 sqrt(2 g / (H2 - H3)) (13), inputs in pump volts."""
        al1 = orifice_slope(x0[0] - x0[1], self.Cd1 * self.a1, self.g, FILM_M)
        head2 = x0[1] - self.H3
        al2 = orifice_slope(head2, self.Cd2 * self.a2, self.g, FILM_M) if head2 > 0 else 0.0
        A = [[-al1 / self.A1, al1 / self.A1], [al1 / self.A2, -(al1 + al2) / self.A2]]
        B = [[self.Gp / self.A1, 0.0], [0.0, self.Gp / self.A2]]
        C = [[self.Gd, 0.0], [0.0, self.Gd]]
        return A, B, C

    def steady_state(self, u: Sequence[float]) -> Vector:
        """Tank 1 passes all of pump 1 to tank 2; the drain passes both pumps.  With
        both pumps off the tanks keep what lies below the drain: H3 here."""
        v1, v2 = self.saturate(u)
        q1, q2 = (self.Gp * v1, self.Gp * v2) if not self.effects_on else self._inflows((v1, v2))
        h2 = self.H3 + head_for_flow(q1 + q2, self.Cd2 * self.a2, self.g, FILM_M)
        h1 = h2 + head_for_flow(q1, self.Cd1 * self.a1, self.g, FILM_M)
        if h1 <= self.hmax:
            return (h1, h2)
        # tank 1 brims over and spills (spill1 of the excess into tank 2);
        # F(H2) = q12(hmax - H2) + spill1 (Qi1 - q12) + Qi2 - drain(H2) = 0,
        # F decreasing in H2: bisect on [H3, hmax] (H2 = hmax when tank 2 spills too)
        lo, hi = self.H3, self.hmax
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            q12, drain = self.flows((self.hmax, mid))
            over = self.spill1 * max(q1 - q12, 0.0) if self.spill1 > 0.0 else 0.0
            if q12 + over + q2 - drain > 0.0:
                lo = mid
            else:
                hi = mid
        return (self.hmax, 0.5 * (lo + hi))

    def steady_inputs(self, levels: Sequence[float | None]) -> OperatingPoint:
        """Both levels set: Qi1 = q12(H1 - H2), Qi2 = drain(H2) - Qi1.  H1 < H2 needs a
        negative inflow to tank 1 (Murray-Smith 5.3: it has no other outlet)."""
        if len(levels) != 2 or levels[0] is None or levels[1] is None:
            raise SteadyStateError("give both levels (H1, H2)")
        h1, h2 = float(levels[0]), float(levels[1])
        for name, h in (("H1", h1), ("H2", h2)):
            if not self.H3 <= h <= self.hmax:
                raise SteadyStateError(f"{name} must be in [{self.H3:g}, {self.hmax:g}] m, got {h:g}")
        q12, q2 = self.flows((h1, h2))
        v1, v2 = q12 / self.Gp, (q2 - q12) / self.Gp
        if h1 < h2:
            raise SteadyStateError(
                f"H1 = {h1:g} m below H2 = {h2:g} m: water would flow back into tank 1, which has no "
                "other outlet, so no pump setting holds it (Murray-Smith 5.3)")
        if v2 < -1e-12:
            raise SteadyStateError(
                f"levels ({h1:g}, {h2:g}) m need pump voltages ({v1:.3g}, {v2:.3g}) V; a pump cannot run "
                "backwards (the drain passes less than tank 1 sends)")
        if max(v1, v2) > self.vmax:
            raise SteadyStateError(f"levels ({h1:g}, {h2:g}) m need pump voltages ({v1:.3g}, {v2:.3g}) V, "
                                   f"above the pumps' {self.vmax:.3g} V")
        v = (v1, max(v2, 0.0))
        if self.effects_on:  # a pump below its threshold moves nothing: what it needs comes on top
            v = tuple(x + t if x > 0.0 else x for x, t in zip(v, (self.vmin1, self.vmin2)))  # type: ignore[assignment]
            if max(v) > self.vmax:
                raise SteadyStateError(f"levels ({h1:g}, {h2:g}) m need pump voltages ({v[0]:.3g}, {v[1]:.3g}) V "
                                       f"with the thresholds, above the pumps' {self.vmax:.3g} V")
        return OperatingPoint((h1, h2), v)
