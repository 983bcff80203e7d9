"""Level-sensor calibration (Desautel, section 2.3; feature B9).

A pressure sensor's voltage is linear in the water height above it, but its gain
and zero drift with the weather, so a lab re-fits them often::

    level = g * volts + b                                     (Desautel 2.3.1)

from steady-state pairs (pump held, tank settled, height read off the scale, sensor
voltage recorded) by least squares, [g, b] = [V 1]^L x with A^L = (A^T A)^-1 A^T.
Pure arithmetic: the DAQ configuration stores the result, the DAQ backend applies it.

The same settled levels give the plant's outlet coefficients (2.3.1): at steady state
each tank's outflow equals its inflow, which is linear in the unknown coefficients, so
they too come from one least-squares solve (:func:`fit_cascade_outlets` for the coupled
tanks, alpha as Desautel defines it; :func:`fit_quadtank_outlets` for the quadruple
tank's outlet areas).

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


@dataclass(frozen=True)
class OutletFit:
    """Outlet coefficients from settled levels and the flow residual's rms (same
    units as the inflows: cm/s for the cascade's beta u, cm^3/s for the quadruple tank)."""

    coefficients: tuple[float, ...]
    rms: float


def _flow_fit(rows: list[list[float]], rhs: list[float], names: str) -> OutletFit:
    """Least squares M c = q, refusing what cannot determine every coefficient.

    numpy loads here: the DAQ configuration imports this module when the `quadtank`
    parser is built, and that must stay light (tests/cli/test_cli_startup.py)."""
    import numpy as np

    M, q = np.array(rows, dtype=float), np.array(rhs, dtype=float)
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(q))):
        raise CalibrationError("every voltage and level must be a finite number")
    if np.linalg.matrix_rank(M) < M.shape[1]:
        raise CalibrationError(f"the settled levels cannot determine {names}: a level is 0 in every pair")
    c, *_ = np.linalg.lstsq(M, q, rcond=None)
    rms = float(np.sqrt(np.mean((M @ c - q) ** 2)))
    return OutletFit(tuple(float(x) for x in c), rms)


def _settled(name: str, columns: Sequence[Sequence[float]], n: int) -> None:
    if n < 1:
        raise CalibrationError("outlet coefficients need at least one settled pair")
    for col in columns:
        if len(col) != n:
            raise CalibrationError(f"{name}: {n} pump voltages but {len(col)} levels")
        if any(not math.isfinite(float(h)) or h < 0 for h in col):
            raise CalibrationError(f"{name}: settled levels must be finite and >= 0 cm")


def fit_cascade_outlets(
    volts: Sequence[float], upper_cm: Sequence[float], lower_cm: Sequence[float],
    beta: float, g: float = 981.0,
) -> OutletFit:
    """alpha1, alpha2 of the coupled tanks from settled levels (Desautel 2.3.1).

    x1' = beta u - alpha1 sqrt(2 g x1), x2' = alpha1 sqrt(2 g x1) - alpha2 sqrt(2 g x2);
    each pair gives two rows, [c1, 0] alpha = beta u and [c1, -c3] alpha = 0, with
    c1 = sqrt(2 g x1), c3 = sqrt(2 g x2); beta (cm/s per V) from the blocked-outlet test.
    """
    _settled("cascade", (upper_cm, lower_cm), len(volts))
    rows: list[list[float]] = []
    rhs: list[float] = []
    for u, x1, x2 in zip(volts, upper_cm, lower_cm):
        c1, c3 = math.sqrt(2 * g * x1), math.sqrt(2 * g * x2)
        rows += [[c1, 0.0], [c1, -c3]]
        rhs += [beta * float(u), 0.0]
    return _flow_fit(rows, rhs, "alpha1 and alpha2")


def fit_quadtank_outlets(
    volts: Sequence[tuple[float, float]], levels_cm: Sequence[Sequence[float]],
    pumps: tuple[float, float], valves: tuple[float, float], g: float = 981.0,
) -> OutletFit:
    """Outlet areas a1..a4 (cm^2) of the quadruple tank from settled levels.

    Per settled pair (v1, v2) with levels h1..h4 and q_i = sqrt(2 g h_i) (Nunes 2.2)::

        a3 q3 = (1 - gamma2) k2 v2        a1 q1 - a3 q3 = gamma1 k1 v1
        a4 q4 = (1 - gamma1) k1 v1        a2 q2 - a4 q4 = gamma2 k2 v2
    """
    _settled("quadruple tank", tuple(zip(*levels_cm)) if levels_cm else ((),) * 4, len(volts))
    if any(len(h) != 4 for h in levels_cm):
        raise CalibrationError("the quadruple tank has four settled levels per pair")
    (k1, k2), (g1, g2) = pumps, valves
    rows: list[list[float]] = []
    rhs: list[float] = []
    for (v1, v2), h in zip(volts, levels_cm):
        q = [math.sqrt(2 * g * float(x)) for x in h]
        rows += [[q[0], 0, -q[2], 0], [0, q[1], 0, -q[3]], [0, 0, q[2], 0], [0, 0, 0, q[3]]]
        rhs += [g1 * k1 * v1, g2 * k2 * v2, (1 - g2) * k2 * v2, (1 - g1) * k1 * v1]
    return _flow_fit(rows, rhs, "every outlet area")
