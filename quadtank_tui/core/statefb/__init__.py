"""State-feedback tracking control with integral action (Desautel, chapters 3-4; B4).

design.py      ZOH model, integrator augmentation, Bessel poles, placement, delta, margins
controller.py  the running controller: u = u_e + L2 x_a - L1 w and the smart integrator
quadtank.py    the quadruple tank's linear model, operating point and level limits

The design takes a plain linear model (A, B, C, x_e, u_e, limits), so any plant that can
be linearized at an operating point can use it.
"""

from __future__ import annotations

from quadtank_tui.core.statefb.controller import AntiWindup, LevelLimit, StateFeedback, u_ssmax
from quadtank_tui.core.statefb.design import (
    BESSEL_POLES,
    Design,
    DesignError,
    OperatingModel,
    bessel_poles,
    design,
    loop_margins,
    robustness,
    zoh,
)

__all__ = [
    "BESSEL_POLES", "AntiWindup", "Design", "DesignError", "LevelLimit", "OperatingModel",
    "StateFeedback", "bessel_poles", "design", "loop_margins", "robustness", "u_ssmax", "zoh",
]
