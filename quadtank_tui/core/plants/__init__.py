"""The plant family: one small interface (base.Plant), the quadruple tank through it,
and the other rigs of the source documents.

Plants by `kind` (the key a `.par` file's PLANT section names):

- ``quadtank``: Johansson's quadruple tank (core.plants.johansson, unchanged)
- ``desautel-qtp``: the same process in Desautel's alpha/beta form (Quanser QTP)
- ``coupled-cascade``: Quanser coupled tanks, one pump (Desautel's CTP)
- ``coupled-tito``: two tanks side by side, two pumps (Murray-Smith)
"""

from __future__ import annotations

from typing import Any, Mapping

from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.base import OperatingPoint, Plant, SteadyStateError
from quadtank_tui.core.plants.coupled import CoupledCascade, CoupledTITO
from quadtank_tui.core.plants.quadtank import DesautelQTP, QuadTank

#: Every plant class by kind.
KINDS: dict[str, type[Plant]] = {
    cls.kind: cls for cls in (QuadTank, DesautelQTP, CoupledCascade, CoupledTITO)
}


def make_plant(kind: str, values: Mapping[str, Any] | None = None) -> Plant:
    """The plant `kind` with its defaults changed by `values` (validated)."""
    try:
        cls = KINDS[kind]
    except KeyError:
        raise PlantError(f"unknown plant {kind!r}; known: {', '.join(KINDS)}") from None
    return cls().with_values(**dict(values or {}))


__all__ = [
    "KINDS", "CoupledCascade", "CoupledTITO", "DesautelQTP", "OperatingPoint", "Plant",
    "PlantError", "QuadTank", "SteadyStateError", "make_plant",
]
