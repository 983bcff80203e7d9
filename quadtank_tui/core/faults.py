"""Faults a teacher can inject into the simulated process (B7), for any plant.

Process faults change the model the simulator integrates:

- ``leak`` tank i: an extra outlet of area `value` at the bottom of the tank, water
  lost to the floor (area in the plant's length unit squared; a plant written per
  unit area, alpha_i = a_i / A_i, takes it as a fraction of the cross-section);
- ``clog`` tank i: the tank's outlet area times `value` in [0, 1) (Murray-Smith's
  partly closed drain tap: tank 2 of the two-input rig);
- ``weak_pump`` pump i: its flow times `value` in [0, 1] (JuliaHub's Dyad example
  halves one pump);
- ``valve_drift`` valve i: the split gamma_i moves by `value` per second (clipped
  to [0, 1]; only a plant with valves).

Sensor faults change what is read (normalized units, a fraction of 10 V):
``sensor_bias`` (+value), ``sensor_drift`` (+value per second since it began),
``sensor_noise`` (Gaussian, standard deviation value, seeded), ``sensor_stuck``
(the reading frozen at `value`, the reading when it stuck).

Everything here is pure: the simulator (engine/sim.py) keeps the active set, the
time and the noise generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.base import RELATIVE_ATOL, Plant, orifice_flow
from quadtank_tui.core.plants.stepping import dopri_advance

#: kind -> (what it targets, what `value` means)
KINDS: dict[str, tuple[str, str]] = {
    "leak": ("tank", "outlet area of the leak (plant's area unit)"),
    "clog": ("tank", "fraction of the outlet left open, 0..1"),
    "weak_pump": ("pump", "fraction of the pump's flow left, 0..1"),
    "valve_drift": ("valve", "change of gamma per second"),
    "sensor_bias": ("sensor", "offset, normalized"),
    "sensor_drift": ("sensor", "offset per second, normalized"),
    "sensor_noise": ("sensor", "standard deviation, normalized"),
    "sensor_stuck": ("sensor", "reading it is stuck at (taken when it sticks)"),
}
SENSOR_KINDS = ("sensor_bias", "sensor_drift", "sensor_noise", "sensor_stuck")


class FaultError(PlantError):
    """A fault the plant cannot have (no such tank, a value out of range)."""


@dataclass(frozen=True)
class Fault:
    """One active fault.  `target` is 1-based; `since` the process time it began (s)."""

    kind: str
    target: int
    value: float = 0.0
    since: float = 0.0

    @property
    def key(self) -> tuple[str, int]:
        return self.kind, self.target

    def label(self) -> str:
        """Short text for the status line and the log: 'leak tank 1 (0.02)'."""
        what = KINDS[self.kind][0]
        value = "" if self.kind == "sensor_stuck" else f" ({self.value:g})"
        return f"{self.kind.replace('_', ' ')} {what} {self.target}{value}"


def check_fault(fault: Fault, plant: Plant) -> Fault:
    """The fault if `plant` can have it; FaultError saying why not."""
    if fault.kind not in KINDS:
        raise FaultError(f"unknown fault {fault.kind!r} (one of {', '.join(KINDS)})")
    what = KINDS[fault.kind][0]
    count = {"tank": len(plant.states), "pump": len(plant.inputs), "sensor": len(plant.outputs),
             "valve": len(plant.valve_names)}[what]
    if count == 0:
        raise FaultError(f"the {plant.kind} plant has no {what}s")
    if isinstance(fault.target, bool) or fault.target not in range(1, count + 1):
        raise FaultError(f"{fault.kind}: {what} must be 1..{count}, got {fault.target!r}")
    v = fault.value
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise FaultError(f"{fault.kind}: value must be a number, got {v!r}")
    if fault.kind == "leak" and not 0.0 < v < plant.area(fault.target - 1):
        raise FaultError(f"leak: area must be in (0, {plant.area(fault.target - 1):g}), got {v:g}")
    if fault.kind == "clog" and not 0.0 <= v < 1.0:
        raise FaultError(f"clog: the open fraction must be in [0, 1), got {v:g}")
    if fault.kind == "weak_pump" and not 0.0 <= v <= 1.0:
        raise FaultError(f"weak_pump: the flow fraction must be in [0, 1], got {v:g}")
    if fault.kind == "sensor_noise" and v < 0:
        raise FaultError(f"sensor_noise: the standard deviation must be >= 0, got {v:g}")
    return fault


@dataclass(frozen=True)
class Faults:
    """The active faults, at most one of a kind per target."""

    active: tuple[Fault, ...] = ()

    def on(self, fault: Fault) -> Faults:
        return Faults(tuple(f for f in self.active if f.key != fault.key) + (fault,))

    def off(self, kind: str, target: int) -> Faults:
        return Faults(tuple(f for f in self.active if f.key != (kind, target)))

    def of(self, kind: str) -> tuple[Fault, ...]:
        return tuple(f for f in self.active if f.kind == kind)

    def __bool__(self) -> bool:
        return bool(self.active)

    def labels(self) -> str:
        """'leak tank 1 (0.02), stuck sensor 2' or ''."""
        return ", ".join(f.label() for f in self.active)


def clogged(plant: Plant, faults: Faults) -> Plant:
    """The plant with its clogged outlets' areas scaled."""
    changes = {plant.outlet_names[f.target - 1]: plant.values()[plant.outlet_names[f.target - 1]] * f.value
               for f in faults.of("clog")}
    return plant.with_values(**changes) if changes else plant


def drift_valves(plant: Plant, faults: Faults, dt: float) -> Plant:
    """The plant after `dt` s of its drifting valves moving."""
    changes = {}
    for f in faults.of("valve_drift"):
        name = plant.valve_names[f.target - 1]
        changes[name] = min(max(plant.values()[name] + f.value * dt, 0.0), 1.0)
    return plant.with_values(**changes) if changes else plant


def advance(plant: Plant, faults: Faults, x: Sequence[float], u: Sequence[float], dt: float,
            inflow: Sequence[float] = ()) -> tuple[float, ...]:
    """Levels after dt s with the pumps held, the process faults acting and `inflow`
    (volume per second into each tank, the plant's units: the disturbance pumps,
    core.disturbance) poured in; without either, exactly ``plant.advance``."""
    p = clogged(plant, faults)
    uu = list(p.saturate(u))
    for f in faults.of("weak_pump"):
        uu[f.target - 1] *= f.value  # a pump's flow is proportional to its voltage
    leaks = [(f.target - 1, f.value) for f in faults.of("leak")]
    poured = [(i, q / p.area(i)) for i, q in enumerate(inflow) if q != 0.0]
    if not leaks and not poured:
        return p.advance(x, uu, dt)
    g = p.gravity
    hi = [s.hi for s in p.states]
    film = 2.5e-4 * max(hi)  # 0.05 mm on a 20 cm tank, as johansson.H_FILM

    def rates(y: Sequence[float]) -> list[float]:
        d = list(p.rhs(y, uu))
        for i, a in leaks:
            d[i] -= orifice_flow(max(y[i], 0.0), a, g, film) / p.area(i)
        for i, rate in poured:
            d[i] += rate
        return d

    return dopri_advance(rates, x, dt, [s.lo for s in p.states], hi, rtol=1e-10, atol=RELATIVE_ATOL * max(hi))


def steady_leak_level(q_in: float, outlet: float, leak: float, g: float) -> float:
    """Hand formula: a tank fed q_in with its outlet and a leak settles where
    (outlet + leak) sqrt(2 g h) = q_in."""
    return (q_in / ((outlet + leak) * math.sqrt(2.0 * g))) ** 2


def measure(y: Sequence[float], faults: Faults, t: float, normal: Sequence[float]) -> tuple[float, ...]:
    """Readings (normalized) with the sensor faults acting at process time t; `normal`
    holds one standard normal draw per sensor (the simulator's seeded generator)."""
    out = list(y)
    for fault in faults.active:
        i = fault.target - 1
        if fault.kind not in SENSOR_KINDS or i >= len(out):
            continue
        if fault.kind == "sensor_bias":
            out[i] += fault.value
        elif fault.kind == "sensor_drift":
            out[i] += fault.value * max(t - fault.since, 0.0)
        elif fault.kind == "sensor_noise":
            out[i] += fault.value * normal[i]
    for fault in faults.of("sensor_stuck"):
        if fault.target - 1 < len(out):
            out[fault.target - 1] = fault.value
    return tuple(out)


def switched(fault: Fault, plant: Plant, t: float, reading: Sequence[float]) -> Fault:
    """The fault as it begins at time t: checked, `since` set, a stuck sensor frozen
    at its present reading."""
    fault = replace(fault, since=t)
    if fault.kind == "sensor_stuck":
        fault = replace(fault, value=float(reading[fault.target - 1]) if fault.target - 1 < len(reading) else 0.0)
    return check_fault(fault, plant)
