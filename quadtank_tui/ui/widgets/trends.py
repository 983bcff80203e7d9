"""The two live trends (M7), drawn with textual-plotext.

Each trend owns its `PlotextPlot.plt` (never the global plotext module) and is
redrawn by the screen's UI timer from the engine's ring buffers, never from the
control loop.  The screen hands down the history once per refresh and only when
a new sample arrived, so a paused process costs nothing over SSH.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np
from textual import events
from textual.reactive import reactive
from textual_plotext import PlotextPlot

from quadtank_tui.ui.messages import ActionRequested

#: Time windows the `z` key cycles through, s.
WINDOWS = (120.0, 300.0, 600.0, 1800.0)
#: Fixed colours per signal, the same in both trends.
COLORS = {"y1": "blue", "y2": "red", "y3": "green", "y4": "orange",
          "u1": "blue", "u2": "red", "ref1": "cyan", "ref2": "magenta"}


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
        """Redraw from the last `window` seconds of every signal."""
        self._history = history
        plt = self.plt
        plt.clear_data()
        t = history["t"]
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
            lo, hi = float(values.min()), float(values.max())
            pad = max(0.02, 0.1 * (hi - lo))
            plt.ylim(lo - pad, hi + pad)
        else:
            plt.ylim(0.0, 1.0)
        self.refresh()

    def on_click(self, event: events.Click) -> None:
        self.post_message(ActionRequested(f"plot_type({self.which!r})"))
