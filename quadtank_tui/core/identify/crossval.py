"""Cross-validation of a linear identified model on another log (Nunes 3.3 checks
the models of one experiment on the data of a second).

The model's elements G_oi(s) e^(-L s) are discretized with a zero-order hold at
the validation log's sampling time (the dead time exact, as identify/sampling and
design/sampled do) and
driven by that log's inputs in deviations from its first row; the initial state
is rest at the first row (the model's state is zero there and its outputs are the
logged first readings), which is how every experiment script here starts a log.
Figures are on the whole log, in the log's units (a fraction of 10 V).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.validation import fit_percent


@dataclass(frozen=True)
class Figure:
    """One output of one validation log: fit %, RMS in the log's units, in V and in
    the level unit (NaN when the sensor gain is not known)."""

    log: str
    output: str
    fit_percent: float
    rms_log: float
    rms_v: float
    rms_level: float
    unit: str

    def to_dict(self) -> dict[str, object]:
        return {"log": self.log, "output": self.output, "fit_percent": self.fit_percent,
                "rms_log_units": self.rms_log, "rms_V": self.rms_v, f"rms_{self.unit}": self.rms_level}


#: An output that moves less than this (log units: two of the log's last digits) is
#: constant: its fit % (error over variation) says nothing, and is reported as NaN.
STILL = 2e-6


#: An output moves when its range exceeds this many times its noise's s.d.
NOISE_RANGES = 8.0


def moves(y: np.ndarray) -> bool:
    """Whether a logged output moves: its range is above two of the log's last digits
    and above :data:`NOISE_RANGES` s.d. of its own noise (estimated robustly from its
    second differences), so a still tank's noisy sensor is not given a fit %."""
    y = np.asarray(y, float)
    span = float(np.ptp(y)) if y.size else 0.0
    if span <= STILL:
        return False
    if y.size < 8:
        return True
    d2 = np.diff(y, n=2)
    sd = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)
    return span > NOISE_RANGES * sd


def figure(log: str, output: str, y: np.ndarray, ym: np.ndarray, volts_per_log_unit: float,
           volts_per_level: float, unit: str) -> Figure:
    """The figures of one output, y and ym in the log's units."""
    e = np.asarray(y, float) - np.asarray(ym, float)
    rms = float(np.sqrt(np.mean(e * e)))
    v = rms * volts_per_log_unit
    fit = fit_percent(y, ym) if moves(y) else float("nan")
    return Figure(log, output, fit, rms, v, v / volts_per_level if volts_per_level else float("nan"), unit)


def simulate_element(g: DelayTF, du: np.ndarray, h: float) -> np.ndarray:
    """The response of g to the deviation input du sampled every h s (ZOH), from rest:
    the one convention of identify/sampling and design/sampled (the dead time exact,
    fractional; row k never sees u_k, a direct term acts one row later)."""
    from quadtank_tui.core.identify.sampling import simulate

    return np.asarray(simulate(np.asarray(g.num, float), np.asarray(g.den, float), h,
                               np.asarray(du, float), g.delay), dtype=float)


def simulate_linear(elements: Mapping[tuple[str, str], DelayTF], outputs: Sequence[str], inputs: Sequence[str],
                    columns: Mapping[str, np.ndarray], h: float, name: str) -> dict[str, np.ndarray]:
    """Each output's model response to a log's inputs, from rest at its first row."""
    for key in (*inputs, *outputs):
        if key not in columns:
            raise IdentificationError(f"{name}: no column {key!r} (logged: {' '.join(columns)})")
    out = {}
    for o in outputs:
        y0 = float(columns[o][0])
        ym = np.full(len(columns[o]), y0)
        for i in inputs:
            u = np.asarray(columns[i], float)
            ym = ym + simulate_element(elements[(o, i)], u - u[0], h)
        out[o] = ym
    return out
