"""State-feedback tracking control with integral action (Desautel, chapters 3-4; B4).

placement.py   ZOH model, integrator augmentation, Bessel poles, placement, delta, margins
tracking.py    the running controller: u = u_e + L2 x_a - L1 w and the smart integrator
quadtank.py    the quadruple tank's linear model, operating point and level limits
plants.py      the same for the other plants of core.plants (the coupled tanks)
settings.py    the STATE FEEDBACK parameters; bessel.py  Table 8

Import from the modules: the package imports nothing, so that the parameter model
(which needs settings.py) never loads scipy (placement.py) in the loop process.

The design takes a plain linear model (A, B, C, x_e, u_e, limits), so any plant that can
be linearized at an operating point can use it.
"""

from __future__ import annotations
