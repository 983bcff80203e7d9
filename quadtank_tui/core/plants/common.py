"""What every plant, and every user of one, shares without the model or numpy: the
errors, the operating-point type, the full scale of an analog signal and Torricelli's
law (each plant's flows are built from it)."""

from __future__ import annotations

import math
from dataclasses import dataclass

Vector = tuple[float, ...]

#: Full scale of every analog signal: normalized 1.0 is 10 V (product.md, "Units").
FULL_SCALE_V = 10.0


class PlantError(ValueError):
    """A parameter or a request the physics cannot honour; the message says which."""

    field: str | None = None


class SteadyStateError(PlantError):
    """No (unique, physical) steady state for the request; the message says why."""


@dataclass(frozen=True)
class OperatingPoint:
    """An equilibrium: levels x (state units, cm on the quadruple tank, tanks 1..4)
    and pump voltages u (V)."""

    x: Vector
    u: Vector


# --- the flow law --------------------------------------------------------------------------

def orifice_flow(head: float, coef: float, g: float, film: float) -> float:
    """Flow c sqrt(2 g head) through an orifice, signed like `head` (water runs from
    the higher level to the lower one), blended over |head| < `film` by
    c sqrt(2 g) (h / sqrt(d)) (3/2 - |h| / (2 d)): value and slope match Torricelli
    at |h| = d, the slope at 0 is finite (johansson.H_FILM explains why)."""
    a = abs(head)
    if a >= film:
        q = coef * math.sqrt(2.0 * g * a)
    else:
        q = coef * math.sqrt(2.0 * g) * (a / math.sqrt(film)) * (1.5 - 0.5 * a / film)
    return q if head >= 0.0 else -q


def orifice_slope(head: float, coef: float, g: float, film: float) -> float:
    """d(orifice_flow)/d(head): c sqrt(g / (2 |h|)) above the film."""
    a = abs(head)
    if a >= film:
        return coef * math.sqrt(g / (2.0 * a))
    return coef * math.sqrt(2.0 * g) / math.sqrt(film) * (1.5 - a / film)


def head_for_flow(q: float, coef: float, g: float, film: float) -> float:
    """Inverse of :func:`orifice_flow` for q >= 0: the head that passes q."""
    q_film = coef * math.sqrt(2.0 * g * film)
    if q >= q_film:
        return (q / (coef * math.sqrt(2.0 * g))) ** 2
    r = max(q, 0.0) / q_film
    return film * (3.0 - math.sqrt(9.0 - 8.0 * r)) / 2.0
