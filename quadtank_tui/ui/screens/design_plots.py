"""The Design screen's plots (issue 28): Nyquist with the 1/Ms circle, |S| and
|T| with the Ms line, the load step, and the reference step of each loop.

The numbers come from core/design (the screen's worker computes them); here
they are only drawn, with plot_kit's braille lines, round ticks and legends
generated from the palette (the title names the colour the curve has).  The
Nyquist plot keeps its aspect (the 1/Ms circle is round); a plot too small to
read says the figures it shows instead (issue 43).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from quadtank_tui.ui.colours import BLUE, GREEN, GREY, ORANGE, RED
from quadtank_tui.ui.widgets import plot_kit as kit
from quadtank_tui.ui.widgets.plot_kit import Series
from quadtank_tui.ui.widgets.plot_view import PlotView

if TYPE_CHECKING:
    from quadtank_tui.core.design.simulate import Response

#: Where the Nyquist plot looks: around -1, where the margins are.
NYQUIST_RE, NYQUIST_IM = (-3.0, 1.0), (-2.0, 1.0)
#: Least canvas (rows, columns) the Nyquist plot is drawn on: at its aspect,
#: fewer rows leave the circle a few dots across.
NYQUIST_MIN = (7, 20)


@dataclass(frozen=True)
class DesignPlots:
    """What the worker computed for the plots of one candidate: L(iω) near -1,
    the grid ω (rad/s) with S and T on it, the load step, each loop's reference
    step (loop number -> response), and the Ms of the design."""

    L: np.ndarray
    w: np.ndarray
    S: np.ndarray
    T: np.ndarray
    load: Response
    steps: dict[int, Response]
    ms: float


def draw_nyquist(plot: PlotView, p: DesignPlots, dark: bool, no_color: bool) -> None:
    """L(iω) over the 1/Ms circle around -1 (solid, its own hue) and -1 marked x,
    a unit as long across as up."""
    # The Ms in the circle's own label: a title run of its own could lose its leading blank
    circle, loop, critical = kit.styles([Series(f"1/Ms circle, Ms {p.ms:.2f}", ORANGE), Series("L(iω)", BLUE),
                                         Series("-1", RED)], dark=dark, no_color=no_color)
    fig = plot.figure
    th = np.linspace(0, 2 * np.pi, 240)
    kit.draw(fig, -1 + np.cos(th) / p.ms, np.sin(th) / p.ms, circle)
    kit.draw(fig, p.L.real, p.L.imag, loop)
    fig.points([-1.0], [0.0], kit.Pen(critical.color, "x", cells=True))
    kit.equal_axes(fig, NYQUIST_RE, NYQUIST_IM, plot.content_size.width, plot.content_size.height)
    fig.min_rows, fig.min_columns = NYQUIST_MIN
    fig.too_small = f"Nyquist: Ms {p.ms:.2f} (the 1/Ms circle around -1 has radius {1 / p.ms:.2f})"
    plot.border_title = kit.legend([loop, circle])  # -1 is the red x on the axis


def draw_sensitivity(plot: PlotView, p: DesignPlots, dark: bool, no_color: bool) -> None:
    """|S| and |T| against ω on a log axis, and the line |S| = Ms."""
    line, s, t = kit.styles([Series("Ms", ORANGE, dotted=True), Series("|S|", BLUE), Series("|T|", GREEN)],
                            dark=dark, no_color=no_color)
    width, height = plot.content_size.width, plot.content_size.height
    lw = np.log10(p.w)
    kit.draw(plot.figure, lw, np.full(len(lw), p.ms), line)
    kit.draw(plot.figure, lw, np.abs(p.T), t)
    kit.draw(plot.figure, lw, np.abs(p.S), s)
    top = max(p.ms, float(np.abs(p.S).max()), float(np.abs(p.T).max()))
    kit.axes(plot.figure, (float(lw[0]), float(lw[-1])), (0.0, top), width, height, xlabel="ω (rad/s)")
    decades = [float(k) for k in range(math.ceil(lw[0]), math.floor(lw[-1]) + 1)]
    plot.figure.xticks = [(k, f"{10.0 ** k:g}") for k in decades]
    plot.border_title = kit.legend([s, t, line]) + f" {p.ms:.2f}"


def draw_load_step(plot: PlotView, resp: Response, dark: bool, no_color: bool) -> None:
    """y and u after a load step d at the input, both divided by d."""
    y, u = kit.styles([Series("y/d", BLUE), Series("u/d", RED)], dark=dark, no_color=no_color)
    width, height = plot.content_size.width, plot.content_size.height
    scale = abs(resp.d) or 1.0
    kit.draw(plot.figure, resp.t, resp.u / scale, u)
    kit.draw(plot.figure, resp.t, resp.y / scale, y)
    both = np.concatenate([resp.y, resp.u]) / scale
    kit.axes(plot.figure, (0.0, float(resp.t[-1])), (float(both.min()), float(both.max())), width, height,
             xlabel="t (s)")
    plot.border_title = kit.legend([y, u], "Load step at u: ")


def draw_reference_steps(plot: PlotView, steps: dict[int, Response], dark: bool, no_color: bool) -> None:
    """Each loop's output after a unit reference step, over the reference."""
    series = [Series("r", GREY, dotted=True)] + [Series(f"y{i}", (BLUE, RED)[i - 1]) for i in sorted(steps)]
    drawn = kit.styles(series, dark=dark, no_color=no_color)
    width, height = plot.content_size.width, plot.content_size.height
    if not steps:
        plot.border_title = "Reference steps: choose a controller (Enter on a row)"
        return
    end = max(settled(r) for r in steps.values())
    kit.draw(plot.figure, np.array([0.0, end]), np.array([1.0, 1.0]), drawn[0])
    for st, i in zip(drawn[1:], sorted(steps)):
        inside = steps[i].t <= end
        kit.draw(plot.figure, steps[i].t[inside], steps[i].y[inside], st)
    top = max(1.0, *(float(r.y.max()) for r in steps.values()))
    kit.axes(plot.figure, (0.0, end), (min(0.0, *(float(r.y.min()) for r in steps.values())), top), width, height,
             xlabel="t (s)")
    plot.figure.too_small = "Reference step: " + "; ".join(step_figures(i, steps[i]) for i in sorted(steps))
    plot.border_title = kit.legend(drawn[1:] + drawn[:1], "Reference step: ")


def step_figures(loop: int, resp: Response, within: float = 0.02) -> str:
    """What a unit step plot shows, in words: the peak and when the output is in
    the band for good ("y1 peak 1.05, within 2 % after 310 s")."""
    away = np.flatnonzero(np.abs(resp.y - resp.r) > within * abs(resp.r or 1.0))
    if len(away) and away[-1] + 1 >= len(resp.t):
        inside = "not settled"
    else:
        inside = f"within {within:.0%} after {float(resp.t[away[-1] + 1]) if len(away) else 0.0:.0f} s"
    return f"y{loop} peak {float(np.max(resp.y)):.2f}, {inside}"


def settled(resp: Response, within: float = 0.02) -> float:
    """Twice the time after which the output stays within `within` of the
    reference (the rest of a simulation run to settle shows nothing), s."""
    away = np.flatnonzero(np.abs(resp.y - resp.r) > within * abs(resp.r or 1.0))
    t_s = float(resp.t[away[-1] + 1]) if len(away) and away[-1] + 1 < len(resp.t) else float(resp.t[-1])
    return min(float(resp.t[-1]), max(2.0 * t_s, float(resp.t[1]) * 10))
