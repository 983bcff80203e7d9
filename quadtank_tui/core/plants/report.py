"""`quadtank analyze` for any plant: the linearization at the operating levels.

The quadruple tank keeps its own report (core.analysis: factored G(s), phase from the
valves); every other plant gets the same figures computed from A, B, C: poles (and
the time constants -1/p), the static gains from the pumps to the controlled sensors
(V/V), transmission zeros and the RGA when the loop is square.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from quadtank_tui.core.analysis import relative_gain_array
from quadtank_tui.core.plants.base import Plant
from quadtank_tui.core.plants.linear import LinearModel


@dataclass(frozen=True, eq=False)
class PlantReport:
    plant: Plant
    levels: tuple[float, ...]
    model: LinearModel
    poles: np.ndarray
    static_gains: np.ndarray
    zeros: np.ndarray | None
    rga: np.ndarray | None

    @property
    def phase(self) -> str:
        if self.zeros is None:
            return "n/a"
        return "nonminimum" if np.any(self.zeros.real >= 0) else "minimum"

    def to_dict(self) -> dict[str, Any]:
        return {
            "plant": self.plant.kind,
            "operating_levels": list(self.levels),
            "level_unit": self.plant.states[0].unit,
            "poles": [[p.real, p.imag] for p in self.poles],
            "time_constants": [float(-1.0 / p.real) for p in self.poles],
            "static_gains": self.static_gains.tolist(),
            "zeros": None if self.zeros is None else [[z.real, z.imag] for z in self.zeros],
            "phase": self.phase,
            "rga": None if self.rga is None else self.rga.tolist(),
        }


def report(plant: Plant, levels: Sequence[float]) -> PlantReport:
    """Linearize at `levels` (pumps to controlled sensors) and derive the figures."""
    m = plant.control_model(levels)
    square = m.C.shape[0] == m.B.shape[1]
    G0 = m.dcgain()
    return PlantReport(plant, tuple(levels), m, m.poles(), G0, m.zeros() if square else None,
                       relative_gain_array(G0) if square and G0.shape[0] > 1 else None)


def format_plant_report(title: str, r: PlantReport) -> str:
    lines = [title, ""]
    unit = r.plant.states[0].unit
    lines.append(f"Operating levels ({unit}): " + "  ".join(
        f"{s.name}={x:.4g}" for s, x in zip(r.plant.states, r.levels)))
    lines.append("Poles (1/s):            " + "  ".join(f"{p.real:+.5f}" for p in r.poles))
    lines.append("Time constants (s):     " + "  ".join(f"{-1 / p.real:.2f}" for p in r.poles))
    outs = ", ".join(r.model.outputs)
    lines.append(f"Static gains G(0) (V/V), pumps {', '.join(r.model.inputs)} to sensors {outs}:")
    for row in r.static_gains:
        lines.append("  [ " + "  ".join(f"{x:9.4g}" for x in row) + " ]")
    if r.zeros is not None:
        zs = ", ".join(f"{z.real:+.5f}" if z.imag == 0 else f"{z.real:+.5f}{z.imag:+.5f}j" for z in r.zeros)
        lines.append(f"Transmission zeros:     {zs or 'none'}")
        lines.append(f"Phase:                  {r.phase}")
    if r.rga is not None:
        lines.append("RGA at s = 0:")
        for row in r.rga:
            lines.append("  [ " + "  ".join(f"{x:7.3f}" for x in row) + " ]")
    return "\n".join(lines)
