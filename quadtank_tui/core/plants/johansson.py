"""Johansson's quadruple tank as pure functions of its constants (Johansson & Nunes;
Nunes 1998, section 2): the flow law, the zero-order-hold step, the steady states,
the settings P- and P+ and the Setup screen's relations.  :class:`~quadtank_tui.core.plants.quadtank.QuadTank`
presents them through the plant interface.

Levels h1..h4 in cm, tanks 1 and 2 below, 3 above 1, 4 above 2.  Pump i delivers
k_i v_i cm^3/s for v_i volts; valve i sends gamma_i of it to the lower tank on its
side and 1 - gamma_i to the upper tank on the other side::

    dh1/dt = -a1/A1 sqrt(2 g h1) + a3/A1 sqrt(2 g h3) + gamma1 k1/A1 v1
    dh2/dt = -a2/A2 sqrt(2 g h2) + a4/A2 sqrt(2 g h4) + gamma2 k2/A2 v2
    dh3/dt = -a3/A3 sqrt(2 g h3) + (1 - gamma2) k2/A3 v2
    dh4/dt = -a4/A4 sqrt(2 g h4) + (1 - gamma1) k1/A4 v1

Everything here is a pure function of its arguments: no clock, no I/O.  The
stepping function integrates the model accurately over one sampling period with
the pump voltages held (zero-order hold; core.plants.stepping), so a simulation does
not depend on the sampling time beyond the hold itself (the original used forward
Euler).

Example
-------
>>> h = advance(P_MINUS.op.x, P_MINUS.op.u, 1.0, P_MINUS.params)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Sequence

from quadtank_tui.core.plants.common import (
    FULL_SCALE_V,
    OperatingPoint,
    PlantError,
    SteadyStateError,
    head_for_flow,
    orifice_flow,
)
from quadtank_tui.core.plants.stepping import Levels, Rhs4, check_step, dopri_advance4

Voltages = tuple[float, float]

@dataclass(frozen=True)
class PlantParams:
    """Physical constants of the rig.  Defaults: the paper's table at P-.

    Attributes
    ----------
    A1, A2, A3, A4 : tank cross-sections, cm^2
    a1, a2, a3, a4 : outlet hole cross-sections, cm^2
    k1, k2 : pump gains, cm^3/(V s)
    gamma1, gamma2 : valve splits, fraction of pump i's flow to lower tank i, [0, 1]
    kc : level sensor gain, V/cm
    g : gravity, cm/s^2
    hmax : tank height = sensor range, cm (20 cm is normalized 1.0 at kc = 0.5)
    """

    A1: float = 28.0
    A2: float = 32.0
    A3: float = 28.0
    A4: float = 32.0
    a1: float = 0.071
    a2: float = 0.057
    a3: float = 0.071
    a4: float = 0.057
    k1: float = 3.33
    k2: float = 3.35
    gamma1: float = 0.70
    gamma2: float = 0.60
    kc: float = 0.50
    g: float = 981.0
    hmax: float = 20.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise PlantError(f"{f.name} must be a finite number, got {value!r}")
        for name in ("A1", "A2", "A3", "A4", "a1", "a2", "a3", "a4", "kc", "g", "hmax"):
            if getattr(self, name) <= 0:
                raise PlantError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("k1", "k2"):
            if getattr(self, name) < 0:
                raise PlantError(f"{name} must be >= 0, got {getattr(self, name)}")
        for name in ("gamma1", "gamma2"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise PlantError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        for i in range(4):
            if self.outlet(i) >= self.area(i):
                raise PlantError(f"a{i + 1} must be smaller than A{i + 1}")

    def area(self, i: int) -> float:
        """Cross-section of tank i (0-based), cm^2."""
        return (self.A1, self.A2, self.A3, self.A4)[i]

    def outlet(self, i: int) -> float:
        """Outlet area of tank i (0-based), cm^2."""
        return (self.a1, self.a2, self.a3, self.a4)[i]

    def with_valves(self, gamma1: float | None = None, gamma2: float | None = None) -> PlantParams:
        """A valve change keeps every other constant (control.md, Setup relations)."""
        return replace(
            self,
            gamma1=self.gamma1 if gamma1 is None else gamma1,
            gamma2=self.gamma2 if gamma2 is None else gamma2,
        )

    def with_tank(self, tank: int, *, area: float | None = None, outlet: float | None = None) -> PlantParams:
        """Change tank `tank`'s (1..4) cross-section and/or outlet, e.g. an object dropped in it."""
        _check_tank(tank)
        changes: dict[str, float] = {}
        if area is not None:
            changes[f"A{tank}"] = area
        if outlet is not None:
            changes[f"a{tank}"] = outlet
        return replace(self, **changes)


@dataclass(frozen=True)
class Setting:
    """A named physical setting: the rig's constants and where it is operated."""

    name: str
    title: str
    params: PlantParams
    op: OperatingPoint = field(compare=False)


#: Minimum-phase setting P- (Johansson & Nunes, section 2; gamma1 + gamma2 = 1.30).
P_MINUS = Setting(
    "minphase",
    "P- (minimum phase)",
    PlantParams(k1=3.33, k2=3.35, gamma1=0.70, gamma2=0.60),
    OperatingPoint(x=(12.4, 12.7, 1.8, 1.4), u=(3.00, 3.00)),
)

#: Nonminimum-phase setting P+ (gamma1 + gamma2 = 0.77 < 1: a RHP zero).
P_PLUS = Setting(
    "nonminphase",
    "P+ (nonminimum phase)",
    PlantParams(k1=3.14, k2=3.29, gamma1=0.43, gamma2=0.34),
    OperatingPoint(x=(12.6, 13.0, 4.8, 4.9), u=(3.15, 3.15)),
)

SETTINGS: dict[str, Setting] = {s.name: s for s in (P_MINUS, P_PLUS)}


# --- Setup-screen relations (control.md) -------------------------------------------

def area_from_diameter(diameter_cm: float) -> float:
    """Cross-section (cm^2) of a round tank of the given inner diameter (cm)."""
    if diameter_cm <= 0:
        raise PlantError(f"diameter must be > 0 cm, got {diameter_cm}")
    return math.pi * diameter_cm**2 / 4.0


def diameter_from_area(area_cm2: float) -> float:
    """Inverse of :func:`area_from_diameter`."""
    if area_cm2 <= 0:
        raise PlantError(f"area must be > 0 cm^2, got {area_cm2}")
    return math.sqrt(4.0 * area_cm2 / math.pi)


def time_constant(area: float, outlet: float, level_cm: float, g: float = 981.0) -> float:
    """Linearized time constant T = (A/a) sqrt(2 h0 / g), s."""
    if level_cm <= 0:
        raise PlantError(f"operating level must be > 0 cm, got {level_cm}")
    return area / outlet * math.sqrt(2.0 * level_cm / g)


def outlet_from_time_constant(area: float, tau_s: float, level_cm: float, g: float = 981.0) -> float:
    """The outlet area that gives time constant `tau_s` at level `level_cm`: a = A sqrt(2 h0/g) / T."""
    if tau_s <= 0:
        raise PlantError(f"time constant must be > 0 s, got {tau_s}")
    if level_cm <= 0:
        raise PlantError(f"operating level must be > 0 cm, got {level_cm}")
    return area * math.sqrt(2.0 * level_cm / g) / tau_s


# --- Units ------------------------------------------------------------------------

def levels_to_normalized(h: Sequence[float], p: PlantParams) -> tuple[float, ...]:
    """Sensor reading in normalized units (fraction of 10 V): y = kc h / 10."""
    return tuple(p.kc * hi / FULL_SCALE_V for hi in h)


def normalized_to_levels(y: Sequence[float], p: PlantParams) -> tuple[float, ...]:
    """Inverse of :func:`levels_to_normalized`, cm."""
    return tuple(yi * FULL_SCALE_V / p.kc for yi in y)


# --- The model ----------------------------------------------------------------------

#: Head (cm) below which the outflow leaves Torricelli's law for a smooth blend to
#: zero.  sqrt(h) has infinite slope at h = 0, so a tank whose equilibrium is a film
#: of water would have a time constant of microseconds and make the model stiff
#: without bound.  Below 0.05 mm (under a 12-bit sensor's 20 cm / 4096) the blend
#: q = a sqrt(2 g) (h / sqrt(d)) (3/2 - h / (2 d)) matches Torricelli's value and
#: slope at h = d and is 0 at h = 0; above it the model is exactly the paper's.
H_FILM = 0.005


def outflow(h: float, a: float, g: float) -> float:
    """Outlet flow (cm^3/s) of a tank at level h (cm) through area a (cm^2): the
    orifice law with the film blend, 0 for an empty tank."""
    return 0.0 if h <= 0.0 else orifice_flow(h, a, g, H_FILM)


def level_for_outflow(q: float, outlet: float, g: float) -> float:
    """Inverse of :func:`outflow`: the level (cm) at which the tank passes q cm^3/s."""
    return head_for_flow(q, outlet, g, H_FILM)


def rhs(h: Sequence[float], v: Sequence[float], p: PlantParams) -> Levels:
    """dh/dt (cm/s) of the nonlinear model.

    Physical limits: a pump does not run backwards (v < 0 acts as 0), an empty tank
    has no outflow (see :data:`H_FILM` for the last 0.05 mm), and a full tank spills
    what would raise it above hmax (the spilled water leaves the process).

    Parameters
    ----------
    h : levels of tanks 1..4, cm
    v : pump voltages, V
    p : the rig's constants

    Returns
    -------
    dh/dt of tanks 1..4, cm/s.
    """
    h1, h2, h3, h4 = h
    return _flows(p, (v[0], v[1]))(h1, h2, h3, h4)


#: Local error tolerances of :func:`advance`, cm.  Chosen so 600 s runs agree with a
#: 1e-12 reference to far better than 1e-6 cm (see tests/core/plants/test_johansson_accuracy.py).
RTOL = 1e-10
ATOL = 1e-10


def _flows(p: PlantParams, vv: Voltages) -> Rhs4:
    """:func:`rhs` for the constants `p` and the voltages `vv` held over a step, with
    every product of constants formed once: the same operations on the same values
    as :func:`rhs`, so the same bits, at half its cost (the simulator's sample is
    mostly this function)."""
    v1 = vv[0] if vv[0] > 0.0 else 0.0
    v2 = vv[1] if vv[1] > 0.0 else 0.0
    g, hmax, sqrt, film = p.g, p.hmax, math.sqrt, H_FILM
    g2 = 2.0 * g  # outflow's 2.0 * g * h is (2.0 * g) * h: the same product, formed once
    a1, a2, a3, a4 = p.a1, p.a2, p.a3, p.a4
    A1, A2, A3, A4 = p.A1, p.A2, p.A3, p.A4
    # In rhs: p.gamma1 * p.k1 * v1 is (gamma1 k1) v1, the same product formed here.
    in1 = p.gamma1 * p.k1 * v1
    in2 = p.gamma2 * p.k2 * v2
    in3 = (1.0 - p.gamma2) * p.k2 * v2
    in4 = (1.0 - p.gamma1) * p.k1 * v1

    def f(h1: float, h2: float, h3: float, h4: float) -> Levels:
        q1 = a1 * sqrt(g2 * h1) if h1 >= film else outflow(h1, a1, g)
        q2 = a2 * sqrt(g2 * h2) if h2 >= film else outflow(h2, a2, g)
        q3 = a3 * sqrt(g2 * h3) if h3 >= film else outflow(h3, a3, g)
        q4 = a4 * sqrt(g2 * h4) if h4 >= film else outflow(h4, a4, g)
        f1 = (-q1 + q3 + in1) / A1
        f2 = (-q2 + q4 + in2) / A2
        f3 = (-q3 + in3) / A3
        f4 = (-q4 + in4) / A4
        if h1 >= hmax and f1 > 0.0:
            f1 = 0.0
        if h2 >= hmax and f2 > 0.0:
            f2 = 0.0
        if h3 >= hmax and f3 > 0.0:
            f3 = 0.0
        if h4 >= hmax and f4 > 0.0:
            f4 = 0.0
        return (f1, f2, f3, f4)

    return f


def _clip(x: float, hmax: float) -> float:
    return 0.0 if x < 0.0 else (hmax if x > hmax else x)


#: Where the last :func:`advance` ended: (plant, v1, v2, levels or None if they were
#: projected, the slope there, the flows).  The simulator's next sample starts there
#: with the same inputs as a rule (Manual, a held wave): that call then takes the
#: flows and its first slope from here instead of forming them again (the same
#: numbers: the plant is the same object, a frozen one, the inputs equal, the levels
#: the same tuple), a seventh of a sample's plant work.  One entry, replaced whole:
#: any thread may call advance.
_end: tuple[PlantParams, float, float, Levels | None, Levels, Rhs4] | None
_end = None


def advance(
    h: Sequence[float],
    v: Sequence[float],
    dt: float,
    p: PlantParams,
    *,
    rtol: float = RTOL,
    atol: float = ATOL,
) -> Levels:
    """Levels after `dt` seconds with pump voltages `v` held constant (ZOH).

    Adaptive Dormand-Prince 5(4) with the levels projected onto [0, hmax] after each
    accepted sub-step (an overfull tank spills, an empty one stays empty).  The
    step control shrinks the sub-step where the flow law bends (a tank running dry,
    a tank reaching the brim) until the local error meets `atol`; :data:`H_FILM`
    bounds the stiffness of a nearly empty tank, so a step never needs to be
    much shorter than a tenth of a second away from those events.

    The four-level form of the one integrator (stepping.dopri_advance4).

    Parameters
    ----------
    h : levels of tanks 1..4 at the start, cm (projected onto [0, hmax] first)
    v : pump voltages held over the step, V
    dt : the step, s (a finite number >= 0; PlantError otherwise)
    p : the rig's constants
    rtol, atol : the local error tolerance, relative and in cm

    Returns
    -------
    The levels of tanks 1..4 after dt, cm, each in [0, hmax].

    >>> advance((10.0, 10.0, 0.0, 0.0), (0.0, 0.0), 0.0, PlantParams())
    (10.0, 10.0, 0.0, 0.0)
    """
    global _end
    check_step(dt)
    hmax = p.hmax
    y1, y2, y3, y4 = float(h[0]), float(h[1]), float(h[2]), float(h[3])
    # Projected onto [0, hmax] (each accepted sub-step is too).
    y1 = 0.0 if y1 < 0.0 else (hmax if y1 > hmax else y1)
    y2 = 0.0 if y2 < 0.0 else (hmax if y2 > hmax else y2)
    y3 = 0.0 if y3 < 0.0 else (hmax if y3 > hmax else y3)
    y4 = 0.0 if y4 < 0.0 else (hmax if y4 > hmax else y4)
    if dt == 0.0:
        return (y1, y2, y3, y4)
    v1, v2 = float(v[0]), float(v[1])
    end = _end
    if end is not None and end[0] is p and end[1] == v1 and end[2] == v2:  # the last call's plant and inputs
        f = end[5]
        k0 = end[4] if h is end[3] else f(y1, y2, y3, y4)  # from where it ended: its slope there
    else:
        f = _flows(p, (v1, v2))
        k0 = f(y1, y2, y3, y4)
    y, smooth, slope = dopri_advance4(f, (y1, y2, y3, y4), k0, dt, hmax, rtol=rtol, atol=atol)
    _end = (p, v1, v2, y if smooth else None, slope, f)
    return y


# --- Steady states ------------------------------------------------------------------

def steady_state_levels(v: Sequence[float], p: PlantParams) -> Levels:
    """Levels (cm) the process settles at with constant pump voltages `v`.

    A tank whose steady level would exceed hmax overflows: it stays at hmax and only
    its outlet flow reaches the tank below.

    Parameters
    ----------
    v : pump voltages, V (a negative one acts as 0)
    p : the rig's constants

    Returns
    -------
    The steady levels of tanks 1..4, cm.
    """
    v1, v2 = max(float(v[0]), 0.0), max(float(v[1]), 0.0)
    h3 = min(level_for_outflow((1 - p.gamma2) * p.k2 * v2, p.a3, p.g), p.hmax)
    h4 = min(level_for_outflow((1 - p.gamma1) * p.k1 * v1, p.a4, p.g), p.hmax)
    q3 = outflow(h3, p.a3, p.g)
    q4 = outflow(h4, p.a4, p.g)
    h1 = min(level_for_outflow(p.gamma1 * p.k1 * v1 + q3, p.a1, p.g), p.hmax)
    h2 = min(level_for_outflow(p.gamma2 * p.k2 * v2 + q4, p.a2, p.g), p.hmax)
    return (h1, h2, h3, h4)


def steady_state_inputs(h1: float, h2: float, p: PlantParams) -> OperatingPoint:
    """Pump voltages that hold the lower tanks at (h1, h2) cm, with the upper levels.

    Solves M v = (a1 sqrt(2 g h1), a2 sqrt(2 g h2)) with
    M = [[gamma1 k1, (1 - gamma2) k2], [(1 - gamma1) k1, gamma2 k2]] (Nunes, 2.2).
    M is singular when gamma1 + gamma2 = 1 (the flows through tanks 1 and 2 are then
    tied); a level pair that needs a negative voltage is not reachable either.

    Parameters
    ----------
    h1, h2 : the lower tanks' levels, cm (>= 0)
    p : the rig's constants

    Returns
    -------
    OperatingPoint: x the levels of tanks 1..4, cm; u the pump voltages, V.
    SteadyStateError when no pump setting holds them (gamma1 + gamma2 = 1, a pump
    that would run backwards, an upper tank that would overflow).
    """
    if h1 < 0 or h2 < 0:
        raise SteadyStateError(f"levels must be >= 0 cm, got ({h1}, {h2})")
    m11, m12 = p.gamma1 * p.k1, (1 - p.gamma2) * p.k2
    m21, m22 = (1 - p.gamma1) * p.k1, p.gamma2 * p.k2
    det = m11 * m22 - m12 * m21  # = k1 k2 (gamma1 + gamma2 - 1)
    scale = max(abs(m11 * m22), abs(m12 * m21), 1e-300)
    if abs(det) <= 1e-12 * scale:
        raise SteadyStateError(
            "gamma1 + gamma2 = 1: the lower-tank flows are tied together, so the "
            "levels cannot be set independently (no unique steady-state input)"
        )
    q1, q2 = outflow(h1, p.a1, p.g), outflow(h2, p.a2, p.g)
    v1 = (m22 * q1 - m12 * q2) / det
    v2 = (-m21 * q1 + m11 * q2) / det
    if v1 < -1e-12 or v2 < -1e-12:
        raise SteadyStateError(
            f"levels ({h1:g}, {h2:g}) cm need pump voltages ({v1:.3g}, {v2:.3g}) V; "
            "a pump cannot run backwards"
        )
    v1, v2 = max(v1, 0.0), max(v2, 0.0)
    h = steady_state_levels((v1, v2), p)
    if h[2] >= p.hmax or h[3] >= p.hmax:
        raise SteadyStateError(f"levels ({h1:g}, {h2:g}) cm would overflow an upper tank")
    return OperatingPoint(x=(h1, h2, h[2], h[3]), u=(v1, v2))


# --- Disturbances (exposed by the simulator while it runs) ---------------------------

def _check_tank(tank: int) -> None:
    if tank not in (1, 2, 3, 4):
        raise PlantError(f"tank must be 1..4, got {tank}")


def add_water(h: Sequence[float], tank: int, amount_cm: float, p: PlantParams) -> Levels:
    """Pour `amount_cm` of level into tank 1..4 (negative removes); overflow spills."""
    _check_tank(tank)
    if not math.isfinite(amount_cm):
        raise PlantError(f"amount must be a finite number, got {amount_cm}")
    out = [float(x) for x in h]
    out[tank - 1] = _clip(out[tank - 1] + amount_cm, p.hmax)
    return (out[0], out[1], out[2], out[3])


def total_volume(h: Sequence[float], p: PlantParams) -> float:
    """Water held in the four tanks, cm^3."""
    return sum(p.area(i) * h[i] for i in range(4))


__all__ = [
    "ATOL", "FULL_SCALE_V", "H_FILM", "P_MINUS", "P_PLUS", "RTOL", "SETTINGS", "Levels", "OperatingPoint",
    "PlantError", "PlantParams", "Setting", "SteadyStateError", "Voltages", "add_water", "advance",
    "area_from_diameter", "diameter_from_area", "level_for_outflow", "levels_to_normalized",
    "normalized_to_levels", "outflow", "outlet_from_time_constant", "rhs", "steady_state_inputs",
    "steady_state_levels", "time_constant", "total_volume",
]
