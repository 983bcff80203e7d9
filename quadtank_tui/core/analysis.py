"""Linearized quadruple-tank process: G(s), time constants, zeros, phase, RGA.

Nunes 1998, section 2.2.  Linearized about levels h0 (the operating point), with
deviations x = h - h0 (cm), u = v - v0 (V), y = kc x (V)::

    dx/dt = [[-1/T1, 0, A3/(A1 T3), 0],      [[g1 k1/A1, 0],
             [0, -1/T2, 0, A4/(A2 T4)],   x +  [0, g2 k2/A2],          u
             [0, 0, -1/T3, 0],                 [0, (1-g2) k2/A3],
             [0, 0, 0, -1/T4]]                 [(1-g1) k1/A4, 0]]

with T_i = (A_i/a_i) sqrt(2 h0_i / g).  The Jacobian depends on the levels only, so
the operating point here is a level set.  The program linearizes at the setting's
operating levels (the paper's table for P-/P+); :func:`analyze` can also be given
the steady state of the setting's pump voltages.

The physics has G12 = (1 - gamma2) k2 c1 / ((1 + s T3)(1 + s T1)) and
G21 = (1 - gamma1) k1 c2 / ((1 + s T4)(1 + s T2)), c_i = T_i kc / A_i; the paper's
printed formula swaps k1 and k2 in these two entries.

Example
-------
>>> from quadtank_tui.core.plants.johansson import P_MINUS
>>> r = analyze(P_MINUS.params, P_MINUS.op.x)
>>> r.phase
'minimum'
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.johansson import PlantParams, time_constant
from quadtank_tui.core.plants.linear import LinearModel, finite_zeros


def time_constants(p: PlantParams, h0: Sequence[float]) -> tuple[float, float, float, float]:
    """T_i = (A_i/a_i) sqrt(2 h0_i / g), s, at levels `h0` (cm); every level must be > 0."""
    h0t = tuple(float(x) for x in h0)
    if len(h0t) != 4:
        raise PlantError("an operating point has four levels")
    for i, x in enumerate(h0t):
        if not 0.0 < x <= p.hmax:
            raise PlantError(f"operating level h{i + 1} must be in (0, {p.hmax:g}] cm, got {x:g}")
    T = [time_constant(p.area(i), p.outlet(i), h0t[i], p.g) for i in range(4)]
    return (T[0], T[1], T[2], T[3])


def linearize(p: PlantParams, h0: Sequence[float]) -> LinearModel:
    """Jacobians of the nonlinear model about levels `h0` (cm), as the plant family's
    LinearModel (core.plants.linear: states h1..h4, inputs v1, v2, outputs y1, y2 in
    volts; x0 = h0); every level must be > 0."""
    T = time_constants(p, h0)
    A = np.array([
        [-1 / T[0], 0.0, p.A3 / (p.A1 * T[2]), 0.0],
        [0.0, -1 / T[1], 0.0, p.A4 / (p.A2 * T[3])],
        [0.0, 0.0, -1 / T[2], 0.0],
        [0.0, 0.0, 0.0, -1 / T[3]],
    ])
    B = np.array([
        [p.gamma1 * p.k1 / p.A1, 0.0],
        [0.0, p.gamma2 * p.k2 / p.A2],
        [0.0, (1 - p.gamma2) * p.k2 / p.A3],
        [(1 - p.gamma1) * p.k1 / p.A4, 0.0],
    ])
    C = np.array([[p.kc, 0.0, 0.0, 0.0], [0.0, p.kc, 0.0, 0.0]])
    return LinearModel.of(A, B, C, x0=tuple(float(x) for x in h0), u0=(), states=("h1", "h2", "h3", "h4"),
                          inputs=("v1", "v2"), outputs=("y1", "y2"))


@dataclass(frozen=True)
class TransferElement:
    """G_ij(s) = gain / prod(1 + s T) for T in `lags` (the process's factored form)."""

    gain: float
    lags: tuple[float, ...]

    def __str__(self) -> str:
        den = "".join(f"(1+{T:.1f}s)" for T in self.lags)
        return f"{self.gain:.3g}/{den}" if den else f"{self.gain:.3g}"


@dataclass(frozen=True)
class Analysis:
    """What the Setup screen and `quadtank analyze` show about a setting."""

    model: LinearModel
    time_constants: tuple[float, float, float, float]
    G: tuple[tuple[TransferElement, TransferElement], tuple[TransferElement, TransferElement]]
    static_gains: np.ndarray
    zeros: tuple[complex, ...]
    phase: str
    rga: np.ndarray | None
    gamma_sum: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: time constants (s), static gains (V/V), zeros [re, im], phase, RGA."""
        return {
            "operating_levels_cm": list(self.model.x0),
            "time_constants": list(self.time_constants),
            "static_gains": self.static_gains.tolist(),
            "zeros": [[z.real, z.imag] for z in self.zeros],
            "phase": self.phase,
            "rga": None if self.rga is None else self.rga.tolist(),
            "gamma_sum": self.gamma_sum,
        }


def transmission_zeros(model: LinearModel) -> tuple[complex, ...]:
    """Finite transmission zeros, sorted by real part (core.plants.linear.finite_zeros:
    the Rosenbrock pencil through scipy.linalg, the same numbers as python-control -
    a test compares them - without its 1.3 s import on every `quadtank analyze`)."""
    return tuple(complex(z) for z in finite_zeros(model.A, model.B, model.C, model.D))


def relative_gain_array(G0: np.ndarray) -> np.ndarray | None:
    """Lambda = G(0) .* inv(G(0))^T; None when G(0) is singular (gamma1 + gamma2 = 1)."""
    if abs(np.linalg.det(G0)) < 1e-12 * max(1.0, float(np.abs(G0).max()) ** 2):
        return None
    return G0 * np.linalg.inv(G0).T


def analyze(p: PlantParams, h0: Sequence[float]) -> Analysis:
    """Linearize at levels `h0` (cm) and derive everything the user is shown.

    The phase follows the valves exactly (Nunes 2.2): minimum phase iff
    gamma1 + gamma2 > 1; at gamma1 + gamma2 = 1 a zero sits at the origin, which the
    paper counts as nonminimum phase.
    """
    m = linearize(p, h0)
    T = time_constants(p, h0)
    c1, c2 = T[0] * p.kc / p.A1, T[1] * p.kc / p.A2
    G = (
        (TransferElement(p.gamma1 * p.k1 * c1, (T[0],)),
         TransferElement((1 - p.gamma2) * p.k2 * c1, (T[2], T[0]))),
        (TransferElement((1 - p.gamma1) * p.k1 * c2, (T[3], T[1])),
         TransferElement(p.gamma2 * p.k2 * c2, (T[1],))),
    )
    G0 = np.array([[G[i][j].gain for j in range(2)] for i in range(2)])
    gsum = p.gamma1 + p.gamma2
    return Analysis(
        model=m,
        time_constants=T,
        G=G,
        static_gains=G0,
        zeros=transmission_zeros(m),
        phase="minimum" if gsum > 1.0 else "nonminimum",
        rga=relative_gain_array(G0),
        gamma_sum=gsum,
    )


def zeros_from_valves(p: PlantParams, h0: Sequence[float]) -> tuple[float, float]:
    """The two zeros from the paper's closed form: roots of
    (1 + s T3)(1 + s T4) - (1 - gamma1)(1 - gamma2) / (gamma1 gamma2); gammas in (0, 1].
    """
    if p.gamma1 <= 0 or p.gamma2 <= 0:
        raise PlantError("the closed form needs gamma1, gamma2 > 0")
    T = time_constants(p, h0)
    eta = (1 - p.gamma1) * (1 - p.gamma2) / (p.gamma1 * p.gamma2)
    r = np.roots([T[2] * T[3], T[2] + T[3], 1.0 - eta])
    lo, hi = sorted(float(x.real) for x in r)
    return lo, hi


def format_report(title: str, a: Analysis) -> str:
    """A readable table for the terminal (used by `quadtank analyze`)."""
    lines = [title, ""]
    lines.append("Operating levels (cm):  " + "  ".join(f"h{i+1}={h:.2f}" for i, h in enumerate(a.model.x0)))
    lines.append("Time constants (s):     " + "  ".join(f"T{i+1}={T:.2f}" for i, T in enumerate(a.time_constants)))
    lines.append("")
    lines.append("Transfer matrix G(s) (V/V):")
    w = max(len(str(e)) for row in a.G for e in row)
    for row in a.G:
        lines.append("  [ " + "   ".join(str(e).ljust(w) for e in row) + " ]")
    lines.append("Static gains G(0):")
    for row in a.static_gains:
        lines.append("  [ " + "  ".join(f"{x:7.3f}" for x in row) + " ]")
    zs = ", ".join(f"{z.real:+.4f}" if z.imag == 0 else f"{z.real:+.4f}{z.imag:+.4f}j" for z in a.zeros)
    lines.append(f"Transmission zeros:     {zs}")
    lines.append(
        f"Phase:                  {a.phase} (gamma1 + gamma2 = {a.gamma_sum:.2f}"
        f" {'>' if a.gamma_sum > 1 else '<=' } 1)"
    )
    if a.rga is None:
        lines.append("RGA at s = 0:           undefined (G(0) singular)")
    else:
        lines.append("RGA at s = 0:")
        for row in a.rga:
            lines.append("  [ " + "  ".join(f"{x:7.3f}" for x in row) + " ]")
    return "\n".join(lines)


__all__ = [
    "Analysis", "LinearModel", "TransferElement", "analyze", "format_report", "linearize",
    "relative_gain_array", "time_constants", "transmission_zeros", "zeros_from_valves",
]
