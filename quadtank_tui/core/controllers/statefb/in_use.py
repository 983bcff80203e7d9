"""The state-feedback design for the plant in use (the one place that picks it).

The quadruple tank of the SIMULATION section keeps its own operating model
(core.controllers.statefb.quadtank: the paper's settings, its operating levels from the
STATE FEEDBACK section); any other plant (a PLANT section: the coupled cascade,
the two-input coupled rig, the Quanser QTP) is designed at its own operating
levels (core.controllers.statefb.plants).  The engine's loop and `quadtank statefb` both ask
here, so the command prints the design the loop runs.
"""

from __future__ import annotations

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.controllers.statefb.placement import Design


def design_in_use(p: Parameters) -> Design:
    """The design `p` asks for on its plant in use at its sampling time;
    ParameterError names the key to change when there is none."""
    if p.process is None:
        from quadtank_tui.core.controllers.statefb.quadtank import design_for

        return design_for(p.quadtank_constants(), p.statefb, p.tsamp)
    from quadtank_tui.core.controllers.statefb.plants import design_for as plant_design

    return plant_design(p.process_plant(), p.process_levels(), p.statefb, p.tsamp)
