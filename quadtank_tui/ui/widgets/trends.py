"""The two live trends (M7), drawn with textual-plotext.

Each trend owns its `PlotextPlot.plt` (never the global plotext module) and is
redrawn by the screen's UI timer from the engine's ring buffers, never from the
control loop.  The screen hands down the history once per refresh and only when
a new sample arrived, so a paused process costs nothing over SSH; `show` itself
redraws only when the newest sample or the view differs from the last drawing.

The y axis is laid out here, not by plotext (issue 17.1): plotext puts a tick at
`round((rows - 1) f)` but draws a value at braille dot `round((4 rows - 1) f)`,
so a label could sit a row away from the curve it names, and two labels could
fall on one row (0.3000 lost at 80x24).  `y_axis` picks a round value per row
and the limits that put every row's value exactly under the dots of that row,
so each label names the row it is on, at every size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator, Mapping

import numpy as np
from rich.console import RenderableType
from textual import events
from textual.reactive import reactive
from textual_plotext import PlotextPlot

from quadtank_tui.ui.messages import ActionRequested

#: Time windows the `z` key cycles through, s.
WINDOWS = (120.0, 300.0, 600.0, 1800.0)
#: Fixed colours per signal, the same in both trends.
COLORS = {"y1": "blue", "y2": "red", "y3": "green", "y4": "orange",
          "u1": "blue", "u2": "red", "ref1": "cyan", "ref2": "magenta"}


#: Rows plotext keeps below and above the canvas (the two x axes and the tick labels).
AXIS_ROWS = 3
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


def y_axis(lo_data: float, hi_data: float, rows: int) -> YAxis:
    """Round values per row covering lo_data..hi_data on `rows` rows.

    plotext draws value v at dot floor(0.5 + (4 rows - 1)(v - lo)/(hi - lo)); with
    hi - lo = step (4 rows - 1)/4 and lo = first step - 3 step/8, row i's dots are
    centred on first + i step exactly, and plotext's tick for that value lands on
    row i too (its rounding stays within 3/8 of a row).  Labels go on the rows
    whose values are multiples of a round label step."""
    rows = max(2, rows)
    if hi_data - lo_data < MIN_SPAN:
        mid = (hi_data + lo_data) / 2
        lo_data, hi_data = mid - MIN_SPAN / 2, mid + MIN_SPAN / 2
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
    for k in (1, 2, 4, 5, 10, 20, 40, 50, 100):
        m = mantissa * k
        m /= 10.0 ** math.floor(math.log10(m) + 1e-9)
        if any(abs(m - nice) < 1e-6 for nice in (1, 2, 2.5, 5)) and math.ceil(rows / k) <= most:
            return k
    return 100


def decimate(n: int, columns: int) -> slice:
    """A stride that keeps about one point per column and always ends on the
    newest sample.  plotext joins the points at braille resolution anyway, and its
    drawing time grows with the points (measured: 4 curves of 460 points 35 ms,
    of 115 points about 12 ms)."""
    step = max(1, math.ceil(n / max(1, columns)))
    return slice((n - 1) % step, None, step)


class Trend(PlotextPlot):
    """One trend: its plot type ("y1 y2 ref1 ref2"), the window and autoscale."""

    plot_type: reactive[str] = reactive("u1 u2")
    window: reactive[float] = reactive(300.0)
    autoscale: reactive[bool] = reactive(True)

    def __init__(self, which: str, **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self.which = which
        self._history: Mapping[str, np.ndarray] | None = None
        self._drawn: tuple[object, ...] = ()
        self._y_range = (0.0, 1.0)

    def _title(self) -> None:
        key = "g" if self.which == "upper" else "G"
        scale = "auto" if self.autoscale else "0..1"
        # The legend is the title, in the curves' colours: plotext's own legend
        # sits on the left of the plot, where a strip chart's data starts.
        self.border_title = " ".join(f"[{COLORS[n]}]{n}[/]" for n in self.plot_type.split())
        self.border_subtitle = f"t in s · {key} type · z {self.window / 60:g} min · Z {scale}"

    def watch_plot_type(self) -> None:
        self._title()

    def watch_window(self) -> None:
        self._title()

    def watch_autoscale(self) -> None:
        self._title()

    def show(self, history: Mapping[str, np.ndarray]) -> None:
        """Redraw from the last `window` seconds of every signal, if the newest
        sample or the view changed since the last drawing."""
        t = history["t"]
        drawn = (len(t), float(t[-1]) if len(t) else None, self.plot_type, self.window, self.autoscale)
        if drawn == self._drawn:
            return
        self._drawn = drawn
        self._history = history
        plt = self.plt
        plt.clear_data()
        t_end = float(t[-1]) if len(t) else 0.0
        lo_t = float(max(0, math.floor(t_end - self.window)))  # whole seconds: round ticks
        plt.xlim(lo_t, max(lo_t + self.window, t_end))
        names = self.plot_type.split()
        if len(t):
            pick = decimate(len(t), max(1, self.size.width))
            for name in names:
                plt.plot(t[pick].tolist(), history[name][pick].tolist(),
                         color=COLORS[name], marker="braille")
        if self.autoscale and len(t):
            values = np.concatenate([history[n] for n in names])
            self._y_range = (float(values.min()), float(values.max()))  # y_axis leaves the margin
        else:
            self._y_range = (0.0, 1.0)
        self.refresh()

    def render(self) -> RenderableType:
        # The y axis is laid out for the rows there are now (a resize re-renders).
        axis = y_axis(*self._y_range, self.size.height - AXIS_ROWS)
        self.plt.ylim(axis.lo, axis.hi)
        self.plt.yticks(list(axis.ticks), list(axis.labels))
        return super().render()

    def on_click(self, event: events.Click) -> None:
        self.post_message(ActionRequested(f"plot_type({self.which!r})"))
