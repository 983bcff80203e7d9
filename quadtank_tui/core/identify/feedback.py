"""Whether a log was taken under feedback (issue 40).

A log taken with the controllers in Automatic holds the references r1/r2, and they
move (a PRBS or steps on them); the pump voltages then depend on the measured
levels through the controllers, the noise reaches u, and a direct fit of y to u
(step, oe, arx, n4sid) is biased: its gains come out wrong with no warning.  This
module only recognizes such a log and says so in one line; the identification
methods here are open-loop ones (the two-stage or indirect method with the
references as instruments is not implemented).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

#: A reference that moves by more than this (log units: 1 mV) is moving.
MOVES = 1e-4


def closed_loop(logs: Sequence[tuple[str, Mapping[str, np.ndarray]]]) -> str | None:
    """One line naming the references that move in which logs, or None (open loop)."""
    found = []
    for name, columns in logs:
        moving = [r for r in ("r1", "r2", "r3", "r4") if r in columns
                  and np.ptp(np.asarray(columns[r], dtype=float)) > MOVES]
        if moving:
            found.append(f"{' '.join(moving)} in {name}")
    if not found:
        return None
    return (f"closed loop: the references move ({'; '.join(found)}), so the pumps followed the levels "
            "through the controllers; these open-loop fits of y to u are biased under feedback: read the "
            "gains with care, or identify from a log taken in Manual")
