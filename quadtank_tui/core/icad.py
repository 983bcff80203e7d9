"""Individual Channel Analysis and Design of a 2x2 loop (Murray-Smith, sections 3-4).

With a diagonal controller diag(k1, k2) around a 2x2 plant G (O'Reilly & Leithead)::

    gamma = g12 g21 / (g11 g22)                      multivariable structure function
    h_i   = k_i g_ii / (1 + k_i g_ii)
    C1 = k1 g11 (1 - gamma h2),  C2 = k2 g22 (1 - gamma h1)   the channels

Each channel is judged like a SISO loop (crossover, gain and phase margins) as long
as gamma h_j stays away from (1, 0); the distance is reported too, with the 2x2
closed loop's poles.  Everything is evaluated from the frequency responses (no
polynomial products, so no cancellations to go wrong).

Units matter (control.md): the plant must be the one the controllers act on.
Murray-Smith's k1, k2 are volts per volt, so the plant is the one from pump volts to
sensor volts, G_V = Gd G_SI Gp.

Example
-------
>>> from quadtank_tui.core.plants import CoupledTITO
>>> G = CoupledTITO().control_model((0.115, 0.071))
>>> r = analyze_icad(G, ((31.0, 5.0), (1.0, 0.0)), ((5.6, 0.56), (1.0, 0.0)))
>>> [round(c.crossover, 2) for c in r.channels]
[0.78, 0.16]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import control
import numpy as np

from quadtank_tui.core.design.frequency import crossings, phase_crossings
from quadtank_tui.core.plants.linear import LinearModel

#: Polynomial coefficients in s, highest power first (a list or a numpy array).
Coefficients = Sequence[float] | np.ndarray
#: A SISO controller as (numerator, denominator).
Rational = tuple[Coefficients, Coefficients]

#: Frequency grid, rad/s: wide enough for a tank (time constants of seconds to hours).
W_MIN, W_MAX, W_POINTS = 1e-5, 1e3, 4000


@dataclass(frozen=True)
class ChannelMargins:
    """A channel's open-loop figures.

    crossover : highest gain-crossover frequency, rad/s (None if |C| never crosses 1)
    phase_margin_deg : smallest phase margin over the gain crossovers
    gain_margin : smallest 1/|C| where the phase crosses -180 deg (inf if it never does)
    """

    crossovers: tuple[float, ...]
    phase_margin_deg: float | None
    gain_margin: float
    phase_crossovers: tuple[float, ...]

    @property
    def crossover(self) -> float | None:
        return self.crossovers[-1] if self.crossovers else None


@dataclass(frozen=True, eq=False)
class IcadResult:
    """What `quadtank icad` prints and the analysis panel shows."""

    w: np.ndarray
    gamma: np.ndarray
    h: tuple[np.ndarray, np.ndarray]
    C: tuple[np.ndarray, np.ndarray]
    channels: tuple[ChannelMargins, ChannelMargins]
    gamma_at_0: float
    distance_to_1: dict[str, tuple[float, float]]
    closed_loop_poles: np.ndarray

    @property
    def stable(self) -> bool:
        return bool(np.all(self.closed_loop_poles.real < 0))

    @property
    def min_distance_to_1(self) -> float:
        """Smallest |1 - gamma h_j(jw)| over j and w (1 - gamma h_j near 0: margins mislead)."""
        return min(self.distance_to_1["gamma_h1"][0], self.distance_to_1["gamma_h2"][0])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready; infinities as null."""
        def num(x: float | None) -> float | None:
            return None if x is None or not math.isfinite(x) else float(x)

        return {
            "crossover": [num(c.crossover) for c in self.channels],
            "phase_margin_deg": [num(c.phase_margin_deg) for c in self.channels],
            "gain_margin": [num(c.gain_margin) for c in self.channels],
            "gamma_at_0": self.gamma_at_0,
            "min_distance_to_1": self.min_distance_to_1,
            "distance_to_1": {k: {"distance": d, "w": w} for k, (d, w) in self.distance_to_1.items()},
            "closed_loop_stable": self.stable,
            "closed_loop_poles": [[p.real, p.imag] for p in self.closed_loop_poles],
        }


def _polyval(c: Coefficients, s: np.ndarray) -> np.ndarray:
    return np.polyval(np.asarray(c, dtype=float), s)


def _controller_response(k: Rational, w: np.ndarray) -> np.ndarray:
    return _polyval(k[0], 1j * w) / _polyval(k[1], 1j * w)


def channel_responses(G: LinearModel, k1: Rational, k2: Rational, w: np.ndarray) -> dict[str, np.ndarray]:
    """gamma, h1, h2, C1, C2 at the frequencies w (rad/s)."""
    if G.C.shape[0] != 2 or G.B.shape[1] != 2:
        raise ValueError(f"ICAD needs a 2x2 plant, got {G.C.shape[0]}x{G.B.shape[1]}")
    g = G.freqresp(w)
    g11, g12, g21, g22 = g[:, 0, 0], g[:, 0, 1], g[:, 1, 0], g[:, 1, 1]
    K1, K2 = _controller_response(k1, w), _controller_response(k2, w)
    gamma = g12 * g21 / (g11 * g22)
    h1 = K1 * g11 / (1 + K1 * g11)
    h2 = K2 * g22 / (1 + K2 * g22)
    return {"gamma": gamma, "h1": h1, "h2": h2,
            "C1": K1 * g11 * (1 - gamma * h2), "C2": K2 * g22 * (1 - gamma * h1)}


def _margins(f: Any, w: np.ndarray, c: np.ndarray) -> ChannelMargins:
    """Crossovers refined by root finding on log|C| and on the unwrapped phase.

    A channel whose controller is zero (a .par with no PI on that loop, as the
    shipped desautel-qtp.par) has C = 0: log|C| = -inf never crosses 0, so it has
    no crossover, which is the answer; numpy is told not to warn about it."""
    with np.errstate(divide="ignore"):
        mag = np.log(np.abs(c))
    phase = np.unwrap(np.angle(c))

    def phase_at(x: float) -> float:  # the branch of the nearest grid point
        ref = np.interp(np.log(x), np.log(w), phase)
        p = float(np.angle(f(x)))
        return p + 2 * math.pi * round((ref - p) / (2 * math.pi))

    # the searches of core.design.frequency, on this channel's numerical phase
    gain_cross = crossings(lambda x: math.log(abs(f(x))), w, mag)
    margins = [((math.degrees(phase_at(wc)) + 180.0) + 180.0) % 360.0 - 180.0 for wc in gain_cross]
    phase_cross = phase_crossings(phase_at, w, phase)
    gains = [1.0 / abs(f(wp)) for wp in phase_cross]
    return ChannelMargins(tuple(gain_cross), min(margins) if margins else None,
                          min(gains) if gains else math.inf, tuple(phase_cross))


def _ss(k: Rational) -> control.StateSpace:
    return control.tf2ss(control.tf(list(k[0]), list(k[1])))


def closed_loop_poles(G: LinearModel, k1: Rational, k2: Rational) -> np.ndarray:
    """Poles of the 2x2 loop y = G diag(k1, k2) (r - y)."""
    L = control.series(control.append(_ss(k1), _ss(k2)), control.ss(G.A, G.B, G.C, G.D))
    cl = control.feedback(L, np.eye(2))
    return np.array(sorted(np.linalg.eigvals(cl.A), key=lambda z: (z.real, z.imag)))


def analyze_icad(G: LinearModel, k1: Rational, k2: Rational, *,
                 w: np.ndarray | None = None) -> IcadResult:
    """The ICAD figures of the loop diag(k1, k2) around the 2x2 plant G."""
    w = np.logspace(math.log10(W_MIN), math.log10(W_MAX), W_POINTS) if w is None else np.asarray(w, float)
    r = channel_responses(G, k1, k2, w)
    def channel(name: str) -> ChannelMargins:
        return _margins(lambda x: channel_responses(G, k1, k2, np.array([x]))[name][0], w, r[name])

    channels = (channel("C1"), channel("C2"))
    G0 = G.dcgain()
    dist = {}
    for name, values in (("gamma", r["gamma"]), ("gamma_h1", r["gamma"] * r["h1"]),
                         ("gamma_h2", r["gamma"] * r["h2"])):
        d = np.abs(1 - values)
        i = int(np.argmin(d))
        dist[name] = (float(d[i]), float(w[i]))
    return IcadResult(
        w=w, gamma=r["gamma"], h=(r["h1"], r["h2"]), C=(r["C1"], r["C2"]),
        channels=channels,
        gamma_at_0=float(G0[0, 1] * G0[1, 0] / (G0[0, 0] * G0[1, 1])),
        distance_to_1=dist,
        closed_loop_poles=closed_loop_poles(G, k1, k2),
    )


def pi_controller(K: float, Ti: float) -> Rational:
    """K (1 + 1 / (Ti s)) = (K Ti s + K) / (Ti s): the PI of the controller matrix."""
    return (K * Ti, K), (Ti, 0.0)


def format_icad(title: str, r: IcadResult) -> str:
    """The table `quadtank icad` prints."""
    def fmt(x: float | None, spec: str) -> str:
        return "none" if x is None else ("inf" if not math.isfinite(x) else format(x, spec))

    lines = [title, "", f"gamma(0) = {r.gamma_at_0:.4f}   (structure function at steady state)", ""]
    lines.append("channel   crossover (rad/s)   phase margin (deg)   gain margin")
    for i, c in enumerate(r.channels, start=1):
        gm = fmt(c.gain_margin, ".3g") if math.isfinite(c.gain_margin) else "inf"
        lines.append(f"C{i}        {fmt(c.crossover, '10.4g'):>17}   {fmt(c.phase_margin_deg, '.1f'):>18}   {gm:>11}")
    lines.append("")
    for name, (d, wd) in r.distance_to_1.items():
        label = name.replace("_", " ")
        lines.append(f"min |1 - {label}(jw)| = {d:.3f} at w = {wd:.3g} rad/s")
    worst = max(p.real for p in r.closed_loop_poles)
    lines.append(f"2x2 closed loop: {'stable' if r.stable else 'UNSTABLE'} (slowest pole real part {worst:.4g})")
    return "\n".join(lines)


__all__ = [
    "ChannelMargins", "IcadResult", "Rational", "analyze_icad", "channel_responses",
    "closed_loop_poles", "format_icad", "pi_controller",
]
