"""A designed PI/PID pair as the parameter changes that put it in the controller
matrix: a decentralized PID with the loops on elements 11 (CONTROLLER ONE) and 22
(CONTROLLER FOUR).  Applying them is an ordinary SetParams, so it is bumpless like
any parameter change (the integrator absorbs a new K; core.controllers.pid)."""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.parameters import Parameters

ELEMENT = {1: "CONTROLLER ONE", 2: "CONTROLLER FOUR"}  # C11, C22 of the matrix


def controller_values(pair: Sequence[PIDTuning | None]) -> dict[str, Any]:
    """The `.par` keys (and values) for the loops given (None: leave that loop)."""
    values: dict[str, Any] = {"CONTROL.Type": "PID", "CONTROL.Structure": "Decentralized"}
    for loop, c in zip((1, 2), pair):
        if c is None:
            continue
        sec = ELEMENT[loop]
        values.update({f"{sec}.K": c.Kc, f"{sec}.Ti": c.Ti, f"{sec}.Td": c.Td,
                       f"{sec}.N": c.N, f"{sec}.b": c.b, f"{sec}.I": 1, f"{sec}.D": int(c.Td > 0)})
    return values


#: A one-pump plant's loop (the cascade: u1 from the lower level y2, reference 2) is
#: element 12 of the matrix, u1 from error 2: CONTROLLER TWO, in the full matrix.
#: CONTROLLER ONE keeps K 0 with its integrator: it holds the input the Manual ->
#: Automatic switch found (bumpless) and takes the pump's saturation excess, the
#: anti-windup the matrix gives the element that owns input 1 (core.controllers.matrix).
ONE_PUMP_ELEMENT = "CONTROLLER TWO"


def one_pump_values(c: PIDTuning) -> dict[str, Any]:
    """The `.par` keys (and values) for a one-pump plant's loop on its controlled
    level; the elements on the missing pump 2 are zeroed."""
    values: dict[str, Any] = {"CONTROL.Type": "PID", "CONTROL.Structure": "FullMatrix"}
    sec = ONE_PUMP_ELEMENT
    values.update({f"{sec}.K": c.Kc, f"{sec}.Ti": c.Ti, f"{sec}.Td": c.Td,
                   f"{sec}.N": c.N, f"{sec}.b": c.b, f"{sec}.I": 1, f"{sec}.D": int(c.Td > 0)})
    values.update({"CONTROLLER ONE.K": 0.0, "CONTROLLER ONE.I": 1, "CONTROLLER ONE.D": 0})
    for other in ("CONTROLLER THREE", "CONTROLLER FOUR"):
        values.update({f"{other}.K": 0.0, f"{other}.I": 0, f"{other}.D": 0})
    return values


def describe_changes(before: Parameters, values: Mapping[str, Any]) -> list[str]:
    """'CONTROLLER ONE.K 3 -> 1.149' for each value that changes."""
    out = []
    for key, new in values.items():
        old = before.get(key)
        old_v = getattr(old, "value", old)
        if old_v != new:
            out.append(f"{key} {old_v:g} -> {new:g}" if isinstance(new, float) and isinstance(old_v, float)
                       else f"{key} {old_v} -> {new}")
    return out


def in_force(params: Parameters, loop: int) -> PIDTuning:
    """The PID element of `loop` (1: CONTROLLER ONE, 2: CONTROLLER FOUR) as the
    parameters hold it: what Apply leaves on a loop with nothing chosen."""
    sec = ELEMENT[loop]

    def num(key: str) -> float:
        v = params.get(f"{sec}.{key}")
        return float(getattr(v, "value", v))

    ti = num("Ti") if num("I") else float("inf")
    return PIDTuning(num("K"), ti, num("Td") if num("D") else 0.0, num("N"), num("b"))
