"""What every small terminal plot of Identify, Design and the Apply preview draws
the same way (issues 28, 43): braille lines, round ticks, a legend outside the
data, and a mark per series without colour, on plot_raster's Figure.

- Lines join their samples dot by dot (2 x 4 dots a cell), so a step is a
  stroke; a reference or a limit is *dotted* (dashed: a cell drawn, a cell left;
  its steps whole).  Where curves share a cell the cell shows both curves'
  dots and takes their colours in turn, so a model lying on the measurement, or
  a prediction on the simulation, stays in sight (plot_raster.py).
- Ticks are 1-2-5 steps with one number of decimals per axis (0.60 0.62 0.64,
  not 0.649 0.637 0.624); lags are whole numbers.
- The legend is text for the plot's border title, generated from the same
  `Series` that draws the curve: each label is written in the colour its curve
  is drawn in (colours.py) after a piece of its line (━ solid, ┈ dotted), and
  under NO_COLOR after its marker.  No title names a colour in words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from textual.content import Content

from quadtank_tui.ui.colours import RGB, Hue
from quadtank_tui.ui.plot_axes import y_axis
from quadtank_tui.ui.widgets.plot_raster import Figure, Pen, equal_aspect
from quadtank_tui.ui.widgets.trend_style import DOTTED_MARKER, MARKERS

#: A legend's sample of a solid and of a dotted line.
LINE_SOLID, LINE_DOTTED = "━", "┈"
#: Rows of a plot that are not canvas: the x axis and its tick labels (the x
#: label takes one more).
FRAME_ROWS = 2
#: Below this many rows of curves a plot gives its x label's row to them (the
#: unit goes after the last tick: "1000 s").
ROOMY_ROWS = 6


@dataclass(frozen=True)
class Series:
    """One curve of a plot: its legend label, hue, and whether it is a
    reference or a limit (dotted)."""

    label: str
    hue: Hue
    dotted: bool = False


@dataclass(frozen=True)
class Style:
    """How a series is drawn here and now: `color` None without colour."""

    series: Series
    color: RGB | None
    marker: str

    @property
    def rich(self) -> str:
        return "" if self.color is None else "rgb({},{},{})".format(*self.color)

    @property
    def pen(self) -> Pen:
        return Pen(self.color, self.marker, dashed=self.series.dotted)

    @property
    def sample(self) -> str:
        """What the legend writes before the label: a piece of the line as drawn
        (solid or dotted), or the marker without colour."""
        if self.color is None:
            return self.marker
        return LINE_DOTTED if self.series.dotted else LINE_SOLID


def styles(series: Sequence[Series], *, dark: bool, no_color: bool) -> list[Style]:
    """The style of each series of one plot."""
    out = []
    solid = 0
    for s in series:
        if no_color:
            marker = DOTTED_MARKER if s.dotted else MARKERS[solid % len(MARKERS)]
            out.append(Style(s, None, marker))
        else:
            out.append(Style(s, s.hue.rgb(dark), MARKERS[solid % len(MARKERS)]))
        solid += not s.dotted
    return out


def legend(drawn: Sequence[Style], lead: str = "") -> Content:
    """`lead` then each series as "━ label", line and label in the series'
    colour (the colour drawn: the title cannot name another)."""
    parts: list[str | tuple[str, str]] = [lead] if lead else []
    for n, st in enumerate(drawn):
        if n:
            parts.append(" ")
        parts.append((f"{st.sample} {st.series.label}", st.rich))
    return Content.assemble(*parts)


def round_ticks(lo: float, hi: float, most: int, *, whole: bool = False) -> tuple[list[float], list[str]]:
    """Values at a 1-2-5 step between lo and hi, at most `most` of them, all
    written with the same decimals; `whole`: steps of at least 1 (lags)."""
    most = max(2, most)
    span = hi - lo
    if not math.isfinite(span) or span <= 0:
        return [lo], [f"{lo:g}"]
    n = math.floor(math.log10(span / most))
    step = 10.0 ** n
    for k in range(12):
        step = (1, 2, 5)[k % 3] * 10.0 ** (n + k // 3)
        if whole and step < 1:
            continue
        if math.floor(hi / step + 1e-9) - math.ceil(lo / step - 1e-9) + 1 <= most:
            break
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    values = [i * step for i in range(math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9) + 1)]
    return values, [f"{v:.{decimals}f}" for v in values]


def draw(fig: Figure, x: np.ndarray, y: np.ndarray, style: Style) -> None:
    """One series on the figure, its samples joined (NaNs break the line)."""
    fig.line(np.asarray(x, float), np.asarray(y, float), style.pen)


def axes(fig: Figure, xlim: tuple[float, float], ylim: tuple[float, float], width: int, height: int, *,
         whole_x: bool = False, xlabel: str | None = None) -> None:
    """Limits and round ticks on both axes for a plot of width x height cells
    (inside its border; a label every 8 columns or more), and the x label.  The
    y axis is laid out as the trends' (plot_axes.y_axis): each row stands for one
    round value and every label sits on the row whose dots show its value, so a
    curve is read off its labels to within a row."""
    y_lo, y_hi = ylim
    if not y_hi > y_lo:
        y_lo, y_hi = y_lo - 0.5, y_hi + 0.5
    unit = None
    if xlabel is not None and height - FRAME_ROWS - 1 < ROOMY_ROWS and "(" in xlabel:
        # a short plot: the x label's row goes to the curves, its unit after the last tick
        unit, xlabel = xlabel[xlabel.index("(") + 1:].rstrip(")"), None
    rows = height - FRAME_ROWS - (xlabel is not None)
    ya = y_axis(y_lo, y_hi, rows, min_span=(y_hi - y_lo) * 1e-3)
    x_lo, x_hi = xlim
    most = max(3, (width - max(map(len, ya.labels), default=1) - 3) // 8)
    xv, xl = round_ticks(x_lo, x_hi, most, whole=whole_x)
    if len(xv) < 3:  # 0..300 in three: 0 200 (steps of 100 make four); take the four
        xv, xl = round_ticks(x_lo, x_hi, most + 1, whole=whole_x)
    if unit is not None and xl:
        xl = xl[:-1] + [f"{xl[-1]} {unit}"]
    fig.xlim, fig.ylim = (x_lo, x_hi), (ya.lo, ya.hi)
    fig.xticks = list(zip(xv, xl))
    fig.yticks = list(zip(ya.ticks, ya.labels))
    fig.xlabel = xlabel


def equal_axes(fig: Figure, xlim: tuple[float, float], ylim: tuple[float, float], width: int,
               height: int) -> None:
    """Limits holding xlim and ylim in which a unit is as long across as up (a
    circle is drawn round: the Nyquist plot), with round ticks on both axes."""
    fig.xlabel = None
    fig.yticks = list(zip(*round_ticks(*ylim, max(2, (height - FRAME_ROWS) // 2))))
    for _ in range(2):  # the y labels' width decides the columns, the columns the y range
        columns, rows = (max(2, n) for n in fig.canvas_size(width, height))
        (x_lo, x_hi), (y_lo, y_hi) = equal_aspect(xlim, ylim, columns, rows)
        fig.yticks = list(zip(*round_ticks(y_lo, y_hi, max(2, rows // 2))))
    # the limits are the first and last dots' centres: half a dot inside the cells' edges
    fig.xlim = (x_lo + (x_hi - x_lo) / (4 * columns), x_hi - (x_hi - x_lo) / (4 * columns))
    fig.ylim = (y_lo + (y_hi - y_lo) / (8 * rows), y_hi - (y_hi - y_lo) / (8 * rows))
    fig.xticks = list(zip(*round_ticks(x_lo, x_hi, max(3, columns // 6))))


def vline(fig: Figure, x: float, hue: Hue, *, dark: bool, no_color: bool) -> None:
    """A vertical line across the canvas at x (where validation starts), after `axes`."""
    fig.line([x, x], list(fig.ylim), Pen(None if no_color else hue.rgb(dark), "│", cells=True))
