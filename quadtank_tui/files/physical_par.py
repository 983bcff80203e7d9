"""A physical fit written into a `.par` of the same plant kind, keeping the file.

The fitted constants replace their lines where they stand (files.par_edit: the
file's comments, its other values and its "Created on" line stay), each followed
by a comment with its uncertainty and the value it replaced::

    alpha1 0.0097864
    % fitted: +- 2.7e-06 (1 standard error); was 0.008

The quadruple tank keeps its constants in SIMULATION as the Setup screen shows
them: an outlet area becomes the time constant at the file's operating level
(a = A sqrt(2 h0 / g) / T), pumps, valves and the sensor gain are written as they
are (a new sensor gain keeps the operating levels in cm); a fitted real-rig effect
(spill3, vmin1, ysat2, ...) goes into a PLANT section of Kind quadtank, added when
the file has none.  The result is read back
by the file reader before it is returned: nothing it would refuse is written.
"""

from __future__ import annotations

from typing import Mapping, Sequence

from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import time_constant
from quadtank_tui.core.plants import Plant, QuadTank
from quadtank_tui.files.par import ParFileError, format_number, parse_par
from quadtank_tui.files.par_edit import with_par_values

#: Significant digits of a fitted constant in the file (far below its uncertainty).
DIGITS = 8


def _number(x: float) -> str:
    return format_number(float(f"{x:.{DIGITS}g}"))


def par_values(old_text: str, name: str, plant: Plant) -> dict[str, str]:
    """The "SECTION.Key" texts that put those of `plant`'s constants that differ
    from the file `old_text`'s into it; ParFileError when the file describes
    another kind of plant."""
    params = parse_par(old_text, name=name).params
    old = params.process_plant()
    if old.kind != plant.kind:
        raise ParFileError(name, f"describes a {old.kind}, the fit is of a {plant.kind}")
    before = old.values()
    changed = {k for k, v in plant.values().items() if float(v) != float(before[k])}
    if not isinstance(plant, QuadTank):
        return {f"PLANT.{k}": _number(plant.values()[k]) for k in plant.values() if k in changed}
    p = plant.params
    h0 = params.operating_levels()
    out = {f"SIMULATION.{key}": _number(getattr(p, const)) for const, key in _QUAD.items() if const in changed}
    out |= {f"PLANT.{k}": _number(plant.values()[k]) for k in plant.effect_names if k in changed}
    for i in range(4):
        if {f"a{i + 1}", "kc"} & changed:
            out[f"SIMULATION.TimeConst{i + 1}"] = format_number(round(
                time_constant(p.area(i), p.outlet(i), h0[i], p.g), 6))
        if "kc" in changed:
            out[f"SIMULATION.OpPoint{i + 1}"] = format_number(round(p.kc * h0[i] / FULL_SCALE_V, 6))
    return out


#: The quadruple tank's constants that SIMULATION holds as they are, and their keys.
_QUAD = {"gamma1": "Valve1", "gamma2": "Valve2", "k1": "Pump1", "k2": "Pump2", "kc": "Sensor"}


def with_fit(old_text: str, name: str, plant: Plant, notes: Mapping[str, str] = {},
             header: Sequence[str] = ()) -> str:
    """`old_text` with `plant`'s constants written in; `notes` (by constant name, as
    the plant calls it) become a comment line under each; `header` lines are added
    as comments after the file's first comment lines.  Checked by the reader."""
    values = par_values(old_text, name, plant)
    if any(k.startswith("PLANT.") for k in values) and not any(
            ln.strip() == "PLANT" for ln in old_text.splitlines()):  # a quadtank's first effect
        newline = "\r\n" if "\r\n" in old_text else "\n"
        old_text = old_text.rstrip("\r\n") + f"{newline}{newline}PLANT{newline}Kind quadtank{newline}"
    new = with_par_values(old_text, values, name)
    lines = new.splitlines(keepends=True)
    newline = "\r\n" if lines and lines[0].endswith("\r\n") else "\n"
    for const, note in notes.items():
        key = _key_of(plant, const)
        at = next((i for i, ln in enumerate(lines) if ln.split(None, 1)[:1] == [key]), None)
        if at is not None:
            lines.insert(at + 1, f"% {const} fitted: {note}{newline}")
    top = 0
    while top < len(lines) and lines[top].startswith("%"):
        top += 1
    lines[top:top] = [f"% {h}{newline}" for h in header]
    new = "".join(lines)
    parse_par(new, name=name)
    return new


def _key_of(plant: Plant, const: str) -> str:
    """The file key a constant's note goes under."""
    if not isinstance(plant, QuadTank):
        return const
    if const in _QUAD:
        return _QUAD[const]
    if const[:1] == "a" and const[1:].isdigit():
        return f"TimeConst{const[1:]}"
    return const
