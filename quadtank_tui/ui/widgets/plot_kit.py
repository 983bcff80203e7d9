"""What every small terminal plot of Identify and Design draws the same way
(issue 28): braille lines, round ticks, a legend outside the data, measured
curves over models and references, and a mark per series without colour.

- Lines use plotext's braille marker (2 x 4 dots a cell); a reference or a
  model is drawn first and *dotted* (a dot every DOT_GAP columns), so the curve
  measured or simulated over it stays whole where the two meet and the
  reference still shows between its dots.
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
from typing import Any, Sequence

import numpy as np
from textual.content import Content

from quadtank_tui.ui.colours import RGB, Hue
from quadtank_tui.ui.plot_axes import y_axis
from quadtank_tui.ui.widgets.trend_style import DOT_GAP, DOTTED_MARKER, MARKERS

#: A legend's sample of a solid and of a dotted line.
LINE_SOLID, LINE_DOTTED = "━", "┈"
#: Rows of a framed plotext plot that are not canvas: the frame's top and bottom
#: lines and the x tick labels (the x label takes one more).
FRAME_ROWS = 3


@dataclass(frozen=True)
class Series:
    """One curve of a plot: its legend label, hue, and whether it is a
    reference or model (dotted, drawn under the others)."""

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
            out.append(Style(s, s.hue.rgb(dark), "braille"))
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


def draw(plt: Any, x: np.ndarray, y: np.ndarray, style: Style, columns: int) -> None:
    """One series on plotext's `plt`: a braille line (or its marker without
    colour), or for a dotted series a dot every DOT_GAP columns of x."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if not len(x):
        return
    if style.series.dotted:
        if len(x) > 1 and np.all(np.diff(x) > 0):
            grid = np.arange(x[0], x[-1] + 1e-12, (x[-1] - x[0]) * DOT_GAP / max(2, columns))
            x, y = grid, np.interp(grid, x, y)
        plt.scatter(x.tolist(), y.tolist(), marker="braille" if style.color is not None else style.marker,
                    color=style.color)
        return
    step = max(1, len(x) // (4 * max(2, columns)))
    plt.plot(x[::step].tolist(), y[::step].tolist(), marker=style.marker, color=style.color)


def axes(plt: Any, xlim: tuple[float, float], ylim: tuple[float, float], width: int, height: int, *,
         whole_x: bool = False, xlabel: str | None = None) -> None:
    """Limits and round ticks on both axes for a framed plot of width x height
    cells (a label every 8 columns or more), and the x label.  The y axis is laid
    out as the trends' (plot_axes.y_axis): each row stands for one round value and
    every label sits on the row whose dots show its value, so a curve is read
    off its labels to within a row (plotext's own rounding put a label up to a
    row away from its value)."""
    y_lo, y_hi = ylim
    if not y_hi > y_lo:
        y_lo, y_hi = y_lo - 0.5, y_hi + 0.5
    rows = height - FRAME_ROWS - (xlabel is not None)
    ya = y_axis(y_lo, y_hi, rows, min_span=(y_hi - y_lo) * 1e-3)
    x_lo, x_hi = xlim
    most = max(3, (width - max(map(len, ya.labels), default=1) - 3) // 8)
    xv, xl = round_ticks(x_lo, x_hi, most, whole=whole_x)
    if len(xv) < 3:  # 0..300 in three: 0 200 (steps of 100 make four); take the four
        xv, xl = round_ticks(x_lo, x_hi, most + 1, whole=whole_x)
    plt.xlim(x_lo, x_hi)
    plt.ylim(ya.lo, ya.hi)
    plt.xticks(xv, xl)
    plt.yticks(list(ya.ticks), list(ya.labels))
    if xlabel is not None:
        plt.xlabel(xlabel)
