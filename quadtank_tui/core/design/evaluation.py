"""The figures of a designed loop (Evaluation), which the continuous-time evaluation
(evaluate.py) and the sampled one (sampled_eval.py) both give, and Andersson's
load step (003_... section 4.3)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import DesignError

#: Andersson's load step at the process input: 10/K (self-regulating) or 10 (integrating).
LOAD_SIZE = 10.0


@dataclass(frozen=True)
class Evaluation:
    """Frequency figures (Ms, margins: deg, ratio, s, rad/s) and time figures of the
    load step (IAE, Emax, u_overshoot) and of a unit setpoint step."""

    Ms: float
    phase_margin_deg: float
    gain_margin: float
    delay_margin: float
    crossover: float
    IAE: float
    Emax: float
    u_overshoot: float
    load: float
    setpoint_overshoot_pct: float
    setpoint_settling: float | None
    stable: bool
    #: 0: the continuous-time loop (Andersson's figures); else the loop sampled at this h, s
    sampling_time: float = 0.0

    def to_dict(self) -> dict[str, float | bool | None]:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in asdict(self).items()}


def load_size(g: DelayTF) -> float:
    """Andersson's load step: 10/K for a self-regulating process, 10 if integrating."""
    if g.integrators:
        return LOAD_SIZE
    k = g.static_gain
    if k == 0.0:
        raise DesignError("the model has zero static gain: no load-step size 10/K")
    return LOAD_SIZE / abs(k)
