"""What the controller box and the snapshot show of the MPC in force: its design
(horizons, operating point) and how its solves go (counts, faults, solve times).

Plain numbers and text, no numpy: the snapshot crosses the session protocol, which
builds it from these annotations without importing the numeric stack.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MPCInfo:
    """The MPC in force.

    horizon, moves : prediction and control horizons (prediction steps)
    step_s : the prediction step, s (the sampling time, or a whole multiple of it)
    x_e, u_e : operating levels (plant units) and pumps (V) of the model
    solves, faults : samples solved, and those whose solve failed (input held)
    slow : solves longer than a tenth of the sampling time (the budget)
    last_ms, p50_ms, p99_ms, max_ms : solve time, ms (percentiles over the last
    solves kept, up to 1000)
    status : the solver's last status ("solved", or why the input was held)
    slack : level-limit violation the last plan accepted (plant units)
    note : what the design says about its operating point ("" usually)
    """

    horizon: int
    moves: int
    x_e: tuple[float, ...]
    u_e: tuple[float, ...]
    solves: int = 0
    faults: int = 0
    slow: int = 0
    last_ms: float = 0.0
    p50_ms: float = 0.0
    p99_ms: float = 0.0
    max_ms: float = 0.0
    status: str = ""
    slack: float = 0.0
    note: str = ""
    step_s: float = 0.0
