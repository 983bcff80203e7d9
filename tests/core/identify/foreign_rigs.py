"""Rigs that are not this project's simulator, for testing identification on data
it did not make.  Nothing here imports quadtank_tui.core.plants: each rig is its own
equations, integrated by its own fixed-step RK4 at a fine step.

- :func:`cascaded_tanks`: the "Cascaded tanks" benchmark rig (Schoukens, Mattsson,
  Wigren, Noel 2016) as its paper describes it: one pump into an upper tank that
  drains into a lower one, outlets with a laminar term beside Torricelli's, an
  upper tank of another cross-section that overflows (part of the excess falls into
  the lower tank, the rest is lost), the lower tank's sensor with an offset and
  saturating at 10 V, noise; 1024 samples at 4 s, a low-pass multisine on the pump.
- :func:`quad_exponent`: a quadruple tank whose outlets follow q = a (2 g h)^0.6
  (not Torricelli's 0.5) and whose lower sensors have hysteresis (a backlash of
  20 mV: the reading follows the level only once it has moved past the band).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

G = 981.0


@dataclass(frozen=True)
class Cascade:
    """The benchmark rig in cm, cm^2, cm^3/s and V."""

    A1: float = 80.0          # upper tank's cross-section
    A2: float = 110.0         # lower tank's
    a1: float = 0.0884        # outlets, cm^2
    a2: float = 0.0787
    lam1: float = 0.12        # laminar terms, cm^2/s
    lam2: float = 0.10
    k: float = 3.4            # pump, cm^3/(V s)
    h1max: float = 18.0       # the upper tank's brim, cm
    h2max: float = 40.0       # the lower tank's (never reached: its sensor saturates first)
    spill: float = 0.5        # share of the upper tank's overflow that falls into the lower one
    kc: float = 0.4           # lower sensor, V/cm
    offset: float = 0.2       # V
    ysat: float = 10.0        # V
    noise: float = 0.01       # V (s.d.)
    quantum: float = 10.0 / 4096


def _q(h: float, a: float, lam: float) -> float:
    return a * math.sqrt(2 * G * max(h, 0.0)) + lam * max(h, 0.0)


def _cascade_rhs(r: Cascade, h: tuple[float, float], u: float) -> tuple[float, float]:
    q1, q2 = _q(h[0], r.a1, r.lam1), _q(h[1], r.a2, r.lam2)
    f1 = r.k * max(u, 0.0) - q1
    over = f1 if h[0] >= r.h1max and f1 > 0 else 0.0
    f2 = q1 + r.spill * over - q2
    if h[1] >= r.h2max and f2 > 0:
        f2 = 0.0
    return ((f1 - over) / r.A1, f2 / r.A2)


def multisine(rows: int, h: float, seed: int, lines: int = 8, mean: float = 5.0, span: float = 4.0) -> np.ndarray:
    """A random-phase multisine on the first `lines` harmonics of the record (a
    low-pass band), scaled to span from mean - span to mean + span V."""
    rng = np.random.default_rng(seed)
    t = np.arange(rows) * h
    period = rows * h
    phases = rng.uniform(0, 2 * np.pi, lines)
    u = sum(np.cos(2 * np.pi * (k + 1) * t / period + phases[k]) for k in range(lines))
    u = np.asarray(u)
    return mean + span * (2 * (u - u.min()) / np.ptp(u) - 1)


def cascaded_tanks(seed: int, rig: Cascade = Cascade(), rows: int = 1024, h: float = 4.0,
                   start: tuple[float, float] = (9.0, 12.0), step: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """(u V, y2 V) of one record: the pump driven by a multisine, the lower level read."""
    u = multisine(rows, h, seed)
    x = list(start)
    y = np.empty(rows)
    n = int(round(h / step))
    noise = np.random.default_rng(seed + 1000).standard_normal(rows) * rig.noise
    for k in range(rows):
        raw = rig.kc * x[1] + rig.offset + noise[k]
        y[k] = min(max(round(raw / rig.quantum) * rig.quantum, 0.0), rig.ysat)
        for _ in range(n):
            k1 = _cascade_rhs(rig, (x[0], x[1]), u[k])
            k2 = _cascade_rhs(rig, (x[0] + step / 2 * k1[0], x[1] + step / 2 * k1[1]), u[k])
            k3 = _cascade_rhs(rig, (x[0] + step / 2 * k2[0], x[1] + step / 2 * k2[1]), u[k])
            k4 = _cascade_rhs(rig, (x[0] + step * k3[0], x[1] + step * k3[1]), u[k])
            x = [min(max(x[i] + step / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]), 0.0),
                     (rig.h1max, rig.h2max)[i]) for i in range(2)]
    return u, y
