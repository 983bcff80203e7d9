"""Starting constants of a physical fit estimated from the logs themselves, not from
the `.par` (another rig's constants can be far from the preset's).

What the logs say plainly: the levels the tanks sit at (a log starts at rest, and
its mean level goes with its mean pump voltage) and how fast the measured levels
answer the pumps (a second-order linear fit's time constants).  For Torricelli
outlets at an operating level h with flow q, a tank's time constant is
T = 2 A h / q (Johansson's T_i = A_i / a_i sqrt(2 h_i / g)), so a time constant
and a level give the flow, and the flow the pump and outlet constants.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from quadtank_tui.core.plants import Plant

Start = tuple[str, np.ndarray]


def time_constants(y: np.ndarray, u: np.ndarray, h: float) -> tuple[float, float] | None:
    """The two time constants (s, slower first) of a second-order ARX fit of y to u
    (least squares on y_k = a1 y_k-1 + a2 y_k-2 + b1 u_k-1 + b2 u_k-2 + c); None if
    its poles are not two real ones in (0, 1)."""
    if y.size < 20 or np.ptp(u) == 0.0:
        return None
    phi = np.column_stack([y[1:-1], y[:-2], u[1:-1], u[:-2], np.ones(y.size - 2)])
    coef, *_ = np.linalg.lstsq(phi, y[2:], rcond=None)
    poles = np.roots([1.0, -coef[0], -coef[1]])
    if np.any(np.abs(poles.imag) > 1e-9) or np.any(poles.real <= 0) or np.any(poles.real >= 1):
        return None
    taus = sorted((-h / math.log(float(p.real)) for p in poles), reverse=True)
    return taus[0], taus[1]


def data_starts(plant: Plant, experiments: Sequence, names: Sequence[str], par: np.ndarray) -> list[Start]:
    """Starts for the free constants `names` (`par`: the `.par`'s values, for the
    constants not estimated here)."""
    if plant.kind == "coupled-cascade":
        return _cascade(plant, experiments, names, par)
    if plant.kind in ("quadtank", "desautel-qtp"):
        return _four_tanks(plant, experiments, names, par)
    return []


def _set(names: Sequence[str], par: np.ndarray, values: dict[str, float]) -> np.ndarray:
    out = par.copy()
    for i, n in enumerate(names):
        if n in values and math.isfinite(values[n]) and values[n] > 0:
            out[i] = values[n]
    return out


def _cascade(plant: Plant, experiments: Sequence, names: Sequence[str], par: np.ndarray) -> list[Start]:
    """Tank 2's mean level and the two time constants of its answer to the pump: the
    flow q = 2 h2 / T2, the pump constant q / u, the outlets q / sqrt(2 g h); tank 1's
    level from the other time constant (which is which, the logs do not say: both)."""
    v = plant.values()
    g = plant.gravity
    out: list[Start] = []
    for e in experiments:
        if 1 not in e.outputs:
            continue
        y2 = e.y[:, e.outputs.index(1)]
        u = e.u[:, 0]
        taus = time_constants(y2, u, e.h)
        span = e.rows * e.h
        if taus is None:
            taus = (span / 10.0, span / 30.0)
        kc2 = v["kc2"]
        h2 = max(float(np.mean(y2)) / kc2, 1e-3 * plant.states[1].hi)
        ubar = max(float(np.mean(u)) - v.get("vmin", 0.0), 1e-6)
        for t2, t1, label in ((taus[1], taus[0], "from the logs (tank 2 the faster)"),
                              (taus[0], taus[1], "from the logs (tank 2 the slower)")):
            q = 2.0 * h2 / t2
            h1 = min(max(0.5 * q * t1 / (v.get("area1", 0.0) or 1.0), 0.02 * plant.states[0].hi), 0.95 * plant.states[0].hi)
            lam_share = 0.1 if any(n.startswith("lam") for n in names) else 0.0
            est = {"beta1": q / ubar,
                   "alpha1": (1 - lam_share) * q / math.sqrt(2 * g * h1),
                   "alpha2": (1 - lam_share) * q / math.sqrt(2 * g * h2),
                   "lam1": lam_share * q / h1, "lam2": lam_share * q / h2}
            out.append((label, _set(names, par, est)))
        break
    return out


def _four_tanks(plant: Plant, experiments: Sequence, names: Sequence[str], par: np.ndarray) -> list[Start]:
    """The `.par`'s constants with the pumps scaled so that the first input's steady
    state has the measured tanks at the first readings (levels go with the square of
    the flow), and a tenth of each outlet's flow there laminar when that is free."""
    from quadtank_tui.core.plants.common import PlantError

    pumps = [n for n in ("k1", "k2", "beta1", "beta2", "beta3", "beta4") if n in names]
    e = experiments[0]
    try:
        x = np.asarray(plant.steady_state(e.u[0]), float)
    except PlantError:
        return []
    gains = np.asarray(plant.output(tuple(1e-3 * s.hi for s in plant.states))) / np.array(
        [1e-3 * s.hi for s in plant.states])
    ratios = []
    for k, o in enumerate(e.outputs):
        meas = float(e.y[:3, k].mean()) / gains[o]
        if x[o] > 1e-3 and meas > 1e-3:
            ratios.append(meas / x[o])
    if not ratios or not pumps:
        return []
    s = math.sqrt(float(np.median(ratios)))
    v = plant.values()
    est = {n: v[n] * s for n in pumps}
    if any(n.startswith("lam") for n in names):
        g = plant.gravity
        for i, outlet in enumerate(plant.outlet_names):
            h = max(float(x[i]) * s * s, 1e-2)
            q = v[outlet] * math.sqrt(2 * g * h)
            est[outlet] = 0.9 * v[outlet]
            est[f"lam{i + 1}"] = 0.1 * q / h
    return [("the .par's scaled to the first levels", _set(names, par, est))]
