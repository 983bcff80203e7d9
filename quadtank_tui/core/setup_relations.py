"""Linked editing of the simulated process on the Setup screen (thesis 5.4, Fig. 39).

A tank is described to the user by three values - operating point, diameter and
time constant - but physically by four: cross-section A = pi d^2 / 4, outlet area
a, operating level h0 and T = (A / a) sqrt(2 h0 / g).  The outlet is the one the
user never types, so it is held fixed (control.md, "Setup-screen relations"):

* a new diameter or operating point keeps the outlet and recomputes T;
* a new time constant keeps the diameter and operating point and so moves the
  outlet (shown to the user as an information, never edited directly).

With a fixed outlet, T scales as d^2 and as sqrt(h0):
T' = T (d'/d)^2 sqrt(h0'/h0).  The valves gamma1, gamma2 (lower tanks 1 and 2)
stand alone.  Every edit returns the `.par` keys it changes, which is exactly what
a window's Set sends as ``SetParams``.

Example (thesis Figure 39: Tank 1 at 0.62, 5.93 cm, 62.16 s)
-------
>>> from quadtank_tui.core.parameters import PRESET
>>> p = PRESET.with_values({"SIMULATION.OpPoint1": 0.62, "SIMULATION.Diameter1": 5.93,
...                         "SIMULATION.TimeConst1": 62.16})
>>> round(edit_tank(p.simulation, 1, diameter=2 * 5.93).get(1).time_constant, 2)
248.64
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Mapping

from quadtank_tui.core.parameters import SimulationSettings
from quadtank_tui.core.ranges import ParameterError, check_number

TANKS = (1, 2, 3, 4)
#: The lower tanks carry the valves: tank i's valve is gamma_i (i = 1, 2).
VALVE_TANKS = (1, 2)


@dataclass(frozen=True)
class TankSetup:
    """One tank as the Setup window shows it (normalized op. point, cm, s, cm^2)."""

    tank: int
    op_point: float
    diameter: float
    time_constant: float
    outlet: float
    valve: float | None

    def values(self) -> dict[str, float]:
        """Its `.par` values by key (the valve only for tanks 1 and 2)."""
        n = self.tank
        out = {
            f"SIMULATION.OpPoint{n}": self.op_point,
            f"SIMULATION.Diameter{n}": self.diameter,
            f"SIMULATION.TimeConst{n}": self.time_constant,
        }
        if self.valve is not None:
            out[f"SIMULATION.Valve{n}"] = self.valve
        return out


def tank_keys(tank: int) -> tuple[str, ...]:
    """The SIMULATION keys a tank's window edits (its Default restores these)."""
    _check_tank(tank)
    keys = tuple(f"SIMULATION.{k}{tank}" for k in ("OpPoint", "Diameter", "TimeConst"))
    return keys + ((f"SIMULATION.Valve{tank}",) if tank in VALVE_TANKS else ())


def outlet(sim: SimulationSettings, tank: int) -> float:
    """The hidden outlet area a_i (cm^2) the tank's three values imply."""
    _check_tank(tank)
    return sim.plant().outlet(tank - 1)


def tank_setup(sim: SimulationSettings, tank: int) -> TankSetup:
    """What the tank window shows for `tank` (1..4)."""
    _check_tank(tank)
    i = tank - 1
    return TankSetup(
        tank=tank,
        op_point=sim.op_points[i],
        diameter=sim.diameters[i],
        time_constant=sim.time_constants[i],
        outlet=outlet(sim, tank),
        valve=sim.valves[i] if tank in VALVE_TANKS else None,
    )


class TankEdit:
    """Result of one linked edit: the new settings and the keys that changed."""

    def __init__(self, before: SimulationSettings, after: SimulationSettings) -> None:
        self.before = before
        self.after = after

    def get(self, tank: int) -> TankSetup:
        return tank_setup(self.after, tank)

    def changes(self) -> dict[str, float]:
        """Changed SIMULATION keys -> new values (what Set sends)."""
        return diff(self.before, self.after)


def edit_tank(
    sim: SimulationSettings,
    tank: int,
    *,
    op_point: float | None = None,
    diameter: float | None = None,
    time_constant: float | None = None,
    valve: float | None = None,
) -> TankEdit:
    """Change some of a tank's values, keeping the others consistent.

    The outlet stays fixed unless `time_constant` is given: then the time constant is
    taken as typed and the outlet follows.  A recomputed time constant is not
    rounded: rounding at every keystroke would let the "fixed" outlet drift with the
    typing path; the `.par` writer keeps any value exactly, and the screen shows six
    digits.  Out-of-range values raise ParameterError naming the full key
    ("SIMULATION.Diameter1"), and nothing is changed.
    """
    _check_tank(tank)
    i = tank - 1
    old = tank_setup(sim, tank)
    op = old.op_point if op_point is None else _number(f"OpPoint{tank}", op_point)
    d = old.diameter if diameter is None else _number(f"Diameter{tank}", diameter)
    if time_constant is not None:
        tau = _number(f"TimeConst{tank}", time_constant)
    elif op == old.op_point and d == old.diameter:
        tau = old.time_constant
    else:
        _check_positive(tank, op, d)
        # The ranges first: scaling by an absurd diameter (1e308) overflows a float.
        _settings(sim, op_points=_put(sim.op_points, i, op), diameters=_put(sim.diameters, i, d))
        tau = old.time_constant * (d / old.diameter) ** 2 * math.sqrt(op / old.op_point)
    valves = sim.valves
    if valve is not None:
        if tank not in VALVE_TANKS:
            raise ParameterError(f"SIMULATION.Valve{tank}", "only the lower tanks 1 and 2 have a valve")
        v = _number(f"Valve{tank}", valve)
        valves = (v, valves[1]) if tank == 1 else (valves[0], v)
    new = _settings(sim, op_points=_put(sim.op_points, i, op), diameters=_put(sim.diameters, i, d),
                    time_constants=_put(sim.time_constants, i, tau), valves=valves)
    return TankEdit(sim, new)


def edit_by_key(sim: SimulationSettings, key: str, value: Any) -> TankEdit:
    """:func:`edit_tank` addressed by a `.par` key ("SIMULATION.Diameter3")."""
    section, _, name = key.partition(".")
    field = name.rstrip("1234")
    arg = {"OpPoint": "op_point", "Diameter": "diameter", "TimeConst": "time_constant", "Valve": "valve"}.get(field)
    if section != "SIMULATION" or arg is None or not name[len(field):].isdigit():
        raise KeyError(f"{key!r} is not a tank value of the Setup window")
    return edit_tank(sim, int(name[len(field):]), **{arg: value})


def diff(before: SimulationSettings, after: SimulationSettings) -> dict[str, float]:
    """The SIMULATION keys whose values differ between two settings, in tank order."""
    out: dict[str, float] = {}
    for tank in TANKS:
        a, b = tank_setup(before, tank).values(), tank_setup(after, tank).values()
        out.update({k: v for k, v in b.items() if v != a[k]})
    return out


def apply_changes(sim: SimulationSettings, changes: Mapping[str, Any]) -> SimulationSettings:
    """Several linked edits in order (a window's fields edited one after another)."""
    for key, value in changes.items():
        sim = edit_by_key(sim, key, value).after
    return sim


# --- helpers ------------------------------------------------------------------------------

def _number(field: str, value: Any) -> float:
    return check_number(f"SIMULATION.{field}", value)


def _check_positive(tank: int, op: float, d: float) -> None:
    """The scaling needs positive values; the model's ranges say which."""
    if op <= 0:
        raise ParameterError(f"SIMULATION.OpPoint{tank}", f"must be > 0, got {op:g}")
    if d <= 0:
        raise ParameterError(f"SIMULATION.Diameter{tank}", f"must be > 0 cm, got {d:g}")


def _settings(sim: SimulationSettings, **changes: Any) -> SimulationSettings:
    """`sim` with `changes`, validated; a refusal names the full key."""
    try:
        return replace(sim, **changes)
    except ParameterError as exc:
        raise ParameterError(f"SIMULATION.{exc.field}", exc.reason) from None


def _put(values: tuple[float, ...], i: int, x: float) -> Any:
    return tuple(x if j == i else v for j, v in enumerate(values))


def _check_tank(tank: int) -> None:
    if tank not in TANKS:
        raise ValueError(f"tank must be 1..4, got {tank!r}")


__all__ = [
    "TANKS", "VALVE_TANKS", "TankEdit", "TankSetup", "apply_changes", "diff", "edit_by_key",
    "edit_tank", "outlet", "tank_keys", "tank_setup",
]
