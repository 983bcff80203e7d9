"""The IST rig's published plant (protocol.py's constants) as the quadruple tank's
PlantParams: what the virtual device serves without --par, and its operating point."""

from __future__ import annotations

from quadtank_tui.core.plants.johansson import PlantParams
from quadtank_tui.daq.ist import protocol as p

#: The rig's published plant (protocol.py): what the virtual device serves without --par.
IST_PLANT = PlantParams(
    A1=p.TANK_AREAS[0], A2=p.TANK_AREAS[1], A3=p.TANK_AREAS[2], A4=p.TANK_AREAS[3],
    a1=p.OUTLET_AREAS[0], a2=p.OUTLET_AREAS[1], a3=p.OUTLET_AREAS[2], a4=p.OUTLET_AREAS[3],
    k1=p.PUMP_K[0], k2=p.PUMP_K[1], gamma1=p.GAMMAS[0], gamma2=p.GAMMAS[1], kc=0.25, g=p.G, hmax=40.0)
#: Its operating point (params/ist-lisbon.par): both pumps at 6 V.
IST_VOLTS = (6.0, 6.0)
