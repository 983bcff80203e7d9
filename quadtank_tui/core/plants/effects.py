"""What real rigs show and a textbook model leaves out, shared by the plants that
learn it: a tank that overflows (a fraction of the excess falls into the tank below
or beside it, the rest leaves the process), a pump that moves no water below a
threshold voltage, a sensor that saturates at the end of its range.

Every effect is off at 0, and a plant runs its plain model while all of its effects
are off, so the published figures stay bit for bit what they were.
"""

from __future__ import annotations

import math
from typing import Sequence

from quadtank_tui.core.plants.common import PlantError


def check_effects(obj: object, fractions: Sequence[str], thresholds: Sequence[str], vmax: float,
                  ranges: Sequence[str]) -> None:
    """Overflow fractions in [0, 1], pump thresholds in [0, vmax), sensor ranges >= 0 V."""
    for name in fractions:
        value = getattr(obj, name)
        if not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
            raise PlantError(f"{name} must be in [0, 1], got {value!r}")
    for name in (*thresholds, *ranges):
        value = getattr(obj, name)
        if not isinstance(value, (int, float)) or not 0.0 <= value < math.inf:
            raise PlantError(f"{name} must be a finite number >= 0 V, got {value!r}")
    for name in thresholds:
        if getattr(obj, name) >= vmax:
            raise PlantError(f"{name} must be below the pump's {vmax:.3g} V, got {getattr(obj, name)!r}")


def any_on(obj: object, names: Sequence[str]) -> bool:
    """Whether one of the effects `names` is on (not 0)."""
    return any(getattr(obj, n) != 0.0 for n in names)


def pump_volts(v: float, vmin: float) -> float:
    """The voltage that moves water: v less the threshold, 0 below it."""
    return max(v - vmin, 0.0) if vmin > 0.0 else v


def sensor(y: float, ysat: float) -> float:
    """A reading clipped at the sensor's range (0: no range)."""
    return min(y, ysat) if ysat > 0.0 else y


def sensor_top(full: float, ysat: float) -> float:
    """The highest reading: the range when it is below the full tank's reading."""
    return min(full, ysat) if ysat > 0.0 else full


def check_laminar(obj: object, names: Sequence[str]) -> None:
    """Laminar outflow coefficients: finite and >= 0 (0: a pure Torricelli outlet)."""
    for name in names:
        value = getattr(obj, name)
        if not isinstance(value, (int, float)) or not 0.0 <= value < math.inf:
            raise PlantError(f"{name} must be a finite number >= 0, got {value!r}")


def check_offsets(obj: object, names: Sequence[str], full_scale: float) -> None:
    """Sensor offsets, V: finite and within the input's full scale either way."""
    for name in names:
        value = getattr(obj, name)
        if not isinstance(value, (int, float)) or not -full_scale <= value <= full_scale:
            raise PlantError(f"{name} must be a number in [-{full_scale:g}, {full_scale:g}] V, got {value!r}")


def head_for_laminar_flow(q: float, coef: float, g: float, lam: float) -> float:
    """The head at which q = coef sqrt(2 g h) + lam h (lam > 0): lam s^2 + c s - q = 0
    in s = sqrt(h), c = coef sqrt(2 g)."""
    c = coef * math.sqrt(2.0 * g)
    q = max(q, 0.0)
    s = (math.sqrt(c * c + 4.0 * lam * q) - c) / (2.0 * lam)
    return s * s


def reading(kc_h: float, offset: float, ysat: float) -> float:
    """A sensor's reading: gain times level plus its offset, clipped at its range."""
    return sensor(kc_h + offset, ysat) if offset != 0.0 else sensor(kc_h, ysat)
