"""Level-sensor calibration (Desautel, section 2.3; feature B9).

A pressure sensor's voltage is linear in the water height above it, but its gain
and zero drift with the weather, so a lab re-fits them often::

    level = g * volts + b                                     (Desautel 2.3.1)

from steady-state pairs (pump held, tank settled, height read off the scale, sensor
voltage recorded) by least squares, [g, b] = [V 1]^L x with A^L = (A^T A)^-1 A^T.
Pure arithmetic: the DAQ configuration stores the result, the DAQ backend applies it.

Example (Desautel's Table 1, sensor 1)
-------
>>> c = fit_sensor((0.5864, 1.3422, 2.2396, 3.2051), (3.5, 7.5, 12.25, 17.75))
>>> round(c.gain, 3), round(c.offset, 3)
(5.431, 0.239)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence


class CalibrationError(ValueError):
    """The pairs cannot determine a gain and an offset (too few, or all one voltage)."""


@dataclass(frozen=True)
class SensorCalibration:
    """level (cm) = gain (cm/V) * volts + offset (cm).

    `rms` is the root-mean-square residual of the fit, cm (0 for a given calibration):
    a large one says a pair was taken before the tank had settled.
    """

    gain: float = 2.0
    offset: float = 0.0
    rms: float = 0.0

    def __post_init__(self) -> None:
        for name in ("gain", "offset", "rms"):
            if not math.isfinite(getattr(self, name)):
                raise CalibrationError(f"{name} must be a finite number, got {getattr(self, name)!r}")
        if self.gain == 0.0:
            raise CalibrationError("gain must not be 0 (the level would not depend on the sensor)")

    def level(self, volts: float) -> float:
        """Level in cm for a sensor reading in volts."""
        return self.gain * volts + self.offset

    def volts(self, level_cm: float) -> float:
        """The sensor reading (V) this calibration expects at `level_cm`."""
        return (level_cm - self.offset) / self.gain


def fit_sensor(volts: Sequence[float], levels_cm: Sequence[float]) -> SensorCalibration:
    """Least-squares gain and offset from steady-state (volts, level) pairs.

    Needs at least two pairs at different voltages; Desautel used four, one per pump
    voltage 4..7 V.  The normal equations of a 2-parameter line are solved in closed
    form on centred data (well conditioned for any sensor range).
    """
    if len(volts) != len(levels_cm):
        raise CalibrationError(f"{len(volts)} voltages but {len(levels_cm)} levels")
    if len(volts) < 2:
        raise CalibrationError("a gain and an offset need at least two steady-state pairs")
    v = [float(x) for x in volts]
    x = [float(h) for h in levels_cm]
    if not all(math.isfinite(a) for a in v + x):
        raise CalibrationError("every voltage and level must be a finite number")
    n = len(v)
    vm = sum(v) / n
    xm = sum(x) / n
    svv = sum((a - vm) ** 2 for a in v)
    if svv <= 1e-12 * max(1.0, vm * vm):
        raise CalibrationError("all pairs have the same voltage: take them at different pump voltages")
    gain = sum((a - vm) * (b - xm) for a, b in zip(v, x)) / svv
    offset = xm - gain * vm
    rms = math.sqrt(sum((gain * a + offset - b) ** 2 for a, b in zip(v, x)) / n)
    return SensorCalibration(gain=gain, offset=offset, rms=rms)
