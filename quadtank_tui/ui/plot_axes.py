"""The axes of the terminal plots, laid out here and not by plotext (issue 17.1).

plotext puts a tick at `round((rows - 1) f)` but draws a value at braille dot
`round((4 rows - 1) f)`, so a label could sit a row away from the curve it
names, and two labels could fall on one row (0.3000 lost at 80x24).  `y_axis`
picks a round value per row and the limits that put every row's value exactly
under the dots of that row, so each label names the row it is on, at every
size; `x_axis` does the same for the columns, in seconds relative to the newest
sample (-60 -40 -20 0).  `decimate` and `visible` pick the samples worth
drawing.

Pure arithmetic on rows, columns and braille dots (math and numpy, no Textual):
the live trends (widgets/trends.py), the small plots of Identify and Design
(widgets/plot_kit.py) and `quadtank log` (commands/logview.py, no TUI) share it.
It stays in ui/ because what it lays out is a terminal plot; nothing below the
UI draws one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

#: Rows plotext keeps below the canvas (the x axis and its labels; the row above
#: the canvas holds the legend instead of a frame line).
AXIS_ROWS = 2
#: Dots per row of the braille marker.
DOTS = 4


@dataclass(frozen=True)
class YAxis:
    """plotext limits and labelled ticks for a canvas of `rows` rows: row i
    (from the bottom) shows the value `first + i step`."""

    lo: float
    hi: float
    ticks: tuple[float, ...]
    labels: tuple[str, ...]


def _nice_steps(smallest: float) -> Iterator[float]:
    """1, 2, 2.5, 5 x 10^n from the one at or below `smallest` upwards."""
    n = math.floor(math.log10(smallest)) if smallest > 0 else -6
    while True:
        for m in (1.0, 2.0, 2.5, 5.0):
            yield m * 10.0 ** n
        n += 1


#: Least span of the y axis (a constant signal gets a few hundredths around it).
MIN_SPAN = 0.02
#: How far, in rows, the data may reach beyond the first and last rows' values
#: (the canvas reaches 3/8 of a row further).
REACH = 0.25


def y_axis(lo_data: float, hi_data: float, rows: int, *, min_span: float = MIN_SPAN) -> YAxis:
    """Round values per row covering lo_data..hi_data on `rows` rows.

    plotext draws value v at dot floor(0.5 + (4 rows - 1)(v - lo)/(hi - lo)); with
    hi - lo = step (4 rows - 1)/4 and lo = first step - 3 step/8, row i's dots are
    centred on first + i step exactly, and plotext's tick for that value lands on
    row i too (its rounding stays within 3/8 of a row).  Labels go on the rows
    whose values are multiples of a round label step."""
    rows = max(2, rows)
    if hi_data - lo_data < min_span:
        mid = (hi_data + lo_data) / 2
        lo_data, hi_data = mid - min_span / 2, mid + min_span / 2
    for step in _nice_steps((hi_data - lo_data) / (rows - 1 + 2 * REACH)):
        lowest = math.ceil(hi_data / step - (rows - 1) - REACH - 1e-9)
        highest = math.floor(lo_data / step + REACH + 1e-9)
        if lowest <= highest:
            first = (lowest + highest) // 2  # the data in the middle
            break
    lo = (first - 3 / 8) * step
    hi = lo + step * (DOTS * rows - 1) / DOTS
    every = _label_every(step, rows)
    label_step = every * step
    decimals = max(0, -math.floor(math.log10(label_step) + 1e-9))
    if abs(label_step * 10 ** decimals - round(label_step * 10 ** decimals)) > 1e-6:
        decimals += 1  # 0.25, 0.025
    values = [(first + i) * step for i in range(rows) if (first + i) % every == 0]
    return YAxis(lo, hi, tuple(values), tuple(f"{v:.{decimals}f}" for v in values))


def _label_every(step: float, rows: int) -> int:
    """Label every k-th row: k such that k step is round (1, 2, 2.5, 5 x 10^n),
    with room between labels (every row of a small plot, else about one in three)."""
    most = max(8, rows // 3 + 1)
    mantissa = step / 10.0 ** math.floor(math.log10(step) + 1e-9)
    round_ks = []
    for k in (1, 2, 4, 5, 10, 20, 40, 50, 100):
        m = mantissa * k
        m /= 10.0 ** math.floor(math.log10(m) + 1e-9)
        if any(abs(m - nice) < 1e-6 for nice in (1, 2, 2.5, 5)):
            round_ks.append(k)
    fits = [k for k in round_ks if math.ceil(rows / k) <= most]
    k = fits[0] if fits else 100
    if rows // k < 3:  # two labels on 9 rows of 0.02 (every 5th): every row rather than so few
        k = max((j for j in round_ks if rows // j >= 3), default=k)
    return k


# --- the time axis ---------------------------------------------------------------------

#: Round tick spacings of the time axis, s.
TIME_STEPS = (1, 2, 5, 10, 15, 20, 30, 60, 120, 300, 600, 900, 1200, 1800, 3600, 7200)
#: Least columns between two time labels ("-1200" and a gap), and what a wide plot
#: keeps (a label every 10 columns or more: about one per 30 s at 120x40, 5 min).
MIN_TICK_COLUMNS = 6
WIDE_TICK_COLUMNS = 10
#: Dots per column of the braille marker.
XDOTS = 2


@dataclass(frozen=True)
class XAxis:
    """plotext limits and labelled ticks for `columns` columns whose right-most
    one shows `end` (s relative to the newest sample): column j (from the left)
    shows end - (columns - 1 - j) per_column."""

    lo: float
    hi: float
    per_column: float
    tick: float
    ticks: tuple[float, ...]
    labels: tuple[str, ...]

    @property
    def first(self) -> float:
        """The value of the left-most column."""
        return self.lo + self.per_column * (XDOTS - 1) / (2 * XDOTS)


def x_axis(window: float, columns: int, end: float = 0.0) -> XAxis:
    """Seconds relative to the newest sample, labelled at round steps (-60 -40
    -20 0) that fall on the columns whose times they name, at every width.

    A label every `tick` seconds, `k` whole columns apart (so per_column = tick /
    k): the columns then show exactly the labels' times.  The span (columns x
    per_column) is the window or a little more (at most one label gap in k).
    The limits are laid out as in `y_axis`, so plotext's dot for a time falls in
    the column its tick is on.  `end` is moved to the nearest column's time
    (`scroll_step` keeps it on a label)."""
    columns = max(2, columns)
    gap = max(MIN_TICK_COLUMNS, min(WIDE_TICK_COLUMNS, columns // 6))
    tick, k = TIME_STEPS[-1], 1
    for tick in TIME_STEPS:
        k = math.floor(tick * columns / window + 1e-9)
        if k >= gap:
            break
    k = max(1, k)
    per_column = tick / k
    end = round(end / per_column) * per_column  # on a column: the labels stay on theirs
    first = end - (columns - 1) * per_column
    lo = first - per_column * (XDOTS - 1) / (2 * XDOTS)
    hi = lo + per_column * (XDOTS * columns - 1) / XDOTS
    ticks = [tick * n for n in range(math.ceil(first / tick - 1e-9), math.floor(end / tick + 1e-9) + 1)]
    return XAxis(lo, hi, per_column, float(tick), tuple(ticks), tuple(f"{v:g}" for v in ticks))


def scroll_step(window: float, columns: int) -> float:
    """How far one press of left/right moves a paused trend, s: about half the
    window, a whole number of labels (so the labels stay round)."""
    tick = x_axis(window, columns).tick
    return max(tick, math.floor(window / 2 / tick + 1e-9) * tick)


def decimate(n: int, columns: int) -> slice:
    """A stride that keeps about one point per column and always ends on the
    newest sample.  plotext joins the points at braille resolution anyway, and its
    drawing time grows with the points (measured: 4 curves of 460 points 35 ms,
    of 115 points about 12 ms)."""
    step = max(1, math.ceil(n / max(1, columns)))
    return slice((n - 1) % step, None, step)


def visible(t: np.ndarray, lo: float, hi: float) -> slice:
    """The samples of sorted times `t` from one before `lo` to `hi` (the line
    into the plot's left edge is drawn too)."""
    a = max(0, int(np.searchsorted(t, lo, side="left")) - 1)
    return slice(a, int(np.searchsorted(t, hi, side="right")))
