"""The two live trends (M7), drawn by the plot kit (plot_raster.py, issue 43):
every sample in view joined into a line, references dashed, and no signal lost
where it shares a cell with another.

Each trend owns its Figure and is redrawn by the screen's UI timer from the engine's ring buffers, never from the
control loop.  The screen hands down the history once per refresh and only when
a new sample arrived, so a paused process costs nothing over SSH; `show` itself
redraws only when the newest sample or the view differs from the last drawing.

Both axes are laid out by ui/plot_axes.py, not by plotext (issue 17.1): each
label names the row or column it is on, at every size; the time axis is in
seconds relative to the newest sample (-60 -40 -20 0), or, with the `c` key, at
round clock times of the samples (trend_clock.py).

The first row is the legend: each signal's value at the right edge of the view,
in the colour its curve has (trend_style.py: one table for both, RGB, a dark and
a light set; marker characters instead under NO_COLOR).  Levels and inputs are
shown normalized or in the plant's units (cm, V); a paused trend scrolls back
through the history; a logged run can be drawn dimmed behind the live curves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from rich.text import Text
from textual import events
from textual.color import Color

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.files.ghost import LoggedRun
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.plot_axes import AXIS_ROWS, MIN_SPAN, visible, x_axis, y_axis
from quadtank_tui.ui.widgets.sized import FitsItsSize
from quadtank_tui.ui.widgets.trend_clock import ClockMap, Ticks, clock_ticks, process_ticks, wall_label
from quadtank_tui.ui.widgets.plot_raster import Pen
from quadtank_tui.ui.widgets.plot_view import PlotView
from quadtank_tui.ui.widgets.trend_style import TraceStyle, trace_styles

#: Time windows the `z` key cycles through, s.
WINDOWS = (120.0, 300.0, 600.0, 1800.0)
# --- units ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Scale:
    """A signal in the unit shown: value = normalized x factor."""

    factor: float = 1.0
    unit: str = ""


NORMALIZED = Scale()


def physical_scales(params: Parameters) -> dict[str, Scale]:
    """Per signal, normalized -> the plant's own units: levels (and their
    references) in the tanks' unit (cm for the quadruple tank: 1.0 is the sensor
    range), pump inputs in V.  A signal the plant does not have stays normalized."""
    plant = params.process_plant()
    states, inputs = plant.states, plant.inputs
    out: dict[str, Scale] = {}
    for i in range(4):
        if i < len(states):
            out[f"y{i + 1}"] = Scale(states[i].full_scale, states[i].unit)
    for i in range(2):
        if i < len(states):
            out[f"ref{i + 1}"] = Scale(states[i].full_scale, states[i].unit)
        if i < len(inputs):
            out[f"u{i + 1}"] = Scale(inputs[i].full_scale, inputs[i].unit)
    return out


# --- the widget ----------------------------------------------------------------------

@dataclass(frozen=True)
class LegendForm:
    """One way of writing the legend: two spaces between entries or one, ref1 or
    r1, the unit, the ghost's name, values without their leading zero and
    markers without a space (NO_COLOR at 80x24)."""

    wide: bool = False
    short: bool = False
    unit: bool = True
    ghost: bool = True
    tight: bool = False


#: The forms tried in turn until one fits the row.
LEGEND_FORMS = (LegendForm(wide=True), LegendForm(), LegendForm(short=True),
                LegendForm(short=True, ghost=False), LegendForm(short=True, ghost=False, unit=False),
                LegendForm(short=True, ghost=False, unit=False, tight=True))


@dataclass(frozen=True)
class TrendView:
    """What a trend shows, besides the samples.

    offset : the view ends this many seconds before the newest sample (0: live)
    scales : per signal, the unit shown (empty: normalized)
    ghost, ghost_start : a logged run drawn dimmed behind the signals, its first
        row at process time ghost_start
    clock : the time axis in clock time of the samples (None: s relative to now)
    """

    plot_type: str = "u1 u2"
    window: float = 300.0
    autoscale: bool = True
    offset: float = 0.0
    scales: tuple[tuple[str, Scale], ...] = ()
    ghost: LoggedRun | None = None
    ghost_start: float = 0.0
    clock: ClockMap | None = None

    @property
    def names(self) -> list[str]:
        return self.plot_type.split()

    def scale(self, name: str) -> Scale:
        return dict(self.scales).get(name, NORMALIZED)

    @property
    def unit(self) -> str:
        """The y axis's unit ("" normalized)."""
        return self.scale(self.names[0]).unit if self.scales else ""


class Trend(FitsItsSize, PlotView):
    """One trend: the legend row (each signal's latest value in its colour), then
    the plot, relative time on x."""

    def __init__(self, which: str, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.which = which
        self.view = TrendView()
        self._history: Mapping[str, np.ndarray] | None = None
        self._drawn: tuple[object, ...] = ()
        self._columns = 0
        self._title()

    @property
    def plot_type(self) -> str:
        return self.view.plot_type

    @property
    def columns(self) -> int:
        """The plot's columns of data at the last drawing (an estimate before)."""
        return self._columns or max(2, self.content_size.width - 7)

    def _title(self) -> None:
        v = self.view
        key = "g" if self.which == "upper" else "G"
        scale = "auto" if v.autoscale else "full"
        unit = v.unit or "norm"
        axis = "s" if v.clock is None else "clock"
        history = self._history if self._history is not None and len(self._history["t"]) else None
        clock = self._clock_known(v, history)
        # The title says what is in view; the subtitle the keys that change it.
        if v.offset > 0 and history is not None:
            end = float(history["t"][-1]) - v.offset
            start = max(0.0, end - v.window)
            if clock is not None:
                title = f"viewing {wall_label(clock, start)}-{wall_label(clock, end)}, End to return"
            else:
                title = f"viewing t = {start:.0f}-{end:.0f} s, End to return"
        elif v.clock is None:
            title = "live, t in s"
        elif clock is not None:
            title = "live, clock time"
        else:  # samples from before the screen watched: process time since the start
            since = v.clock.since
            title = "live, t h:m:s" + ("" if since is None else f", clock from {wall_label(v.clock, since)}")
        if v.ghost is not None:
            title += f" · ghost {v.ghost.name}"
        keys = f"{key} type · z {v.window / 60:g} min · Z {scale} · u {unit} · c {axis}"
        # the border's corners and a line and a space each side (34 at 80x24)
        room = self.size.width - 6 if self.size.width else 34
        short = keys.replace(" type", "", 1)
        for form in (keys, short, short.replace(" min", "m"), short.replace(" min", "m").replace(" · ", "·")):
            if len(form) <= room:
                break
        self.border_title, self.border_subtitle = title, form

    def fit_to_size(self) -> None:
        self._title()  # the subtitle's form depends on the width

    def _clock_known(self, view: TrendView, history: Mapping[str, np.ndarray] | None) -> ClockMap | None:
        """The view's clock, if it knows the wall clock of every sample in view."""
        clock = view.clock
        if clock is None or clock.since is None:
            return None
        if history is None:
            return clock
        t = history["t"]
        x = x_axis(view.window, self.columns, -view.offset)
        oldest_in_view = t[visible(t - t[-1], x.first, -view.offset)]
        return clock if not len(oldest_in_view) or clock.since <= float(oldest_in_view[0]) + 1e-9 else None

    def show(self, history: Mapping[str, np.ndarray], view: TrendView | None = None) -> None:
        """Redraw from `history` as `view` says, if the newest sample or the view
        changed since the last drawing."""
        view = view or self.view
        t = history["t"]
        drawn = (len(t), float(t[-1]) if len(t) else None, view)
        if drawn == self._drawn:
            return
        self._drawn = drawn
        self._history, self.view = history, view
        self._title()
        self.refresh()

    # --- drawing ---------------------------------------------------------------------

    def _styles(self, names: list[str]) -> dict[str, TraceStyle]:
        surface = self.app.theme_variables.get("surface", "#1e1e1e")
        return trace_styles(names, dark=self.app.current_theme.dark, no_color=self.app.no_color,
                            background=Color.parse(surface).rgb)

    def render(self) -> Text:
        width, height = self.content_size.width, self.content_size.height
        view, history = self.view, self._history
        names = view.names
        styles = self._styles(names)
        t = history["t"] if history is not None else np.zeros(0)
        t_new = float(t[-1]) if len(t) else 0.0
        ghost = self._ghost_curves(t_new)
        fig = self.figure
        fig.clear()
        plot_height = max(1, height - 1)  # the legend takes the first row

        # y first: the labels' width decides the columns left for the data.
        rows = plot_height - AXIS_ROWS
        yaxis = y_axis(*self._y_range(view, history, ghost), rows,
                       min_span=MIN_SPAN * view.scale(names[0]).factor)
        fig.yticks = list(zip(yaxis.ticks, yaxis.labels))
        columns = self._columns = max(2, fig.canvas_size(width, plot_height)[0])
        xaxis = x_axis(view.window, columns, -view.offset)
        x_lo, x_hi = xaxis.first - xaxis.per_column, -view.offset
        fig.ylim, fig.xlim = (yaxis.lo, yaxis.hi), (xaxis.lo, xaxis.hi)
        if view.clock is None:
            fig.xticks = list(zip(xaxis.ticks, xaxis.labels))
        else:
            ticks = self._clock_axis(view, history, t_new, xaxis.first, xaxis.per_column, columns)
            fig.xticks = [(xaxis.first + c * xaxis.per_column, label) for c, label in zip(ticks.columns, ticks.labels)]

        for name, (gx, gy) in ghost.items():  # first: in a cell shared with a live curve it takes turns
            pick = visible(gx, x_lo, x_hi)
            fig.line(gx[pick], gy[pick], Pen(styles[name].ghost_color, styles[name].ghost_marker))
        latest: dict[str, float] = {}
        if history is not None and len(t):
            x = t - t_new
            pick = visible(x, x_lo, x_hi)
            # References first and dashed: where an output lies on its reference the
            # shared cells take the two colours in turn, so both stay in sight.
            for name in sorted(names, key=lambda n: not n.startswith("ref")):
                y = history[name][pick] * view.scale(name).factor
                if not len(y):
                    continue
                latest[name] = float(y[-1])
                fig.line(x[pick], y, Pen(styles[name].color, styles[name].marker, dashed=name.startswith("ref")))
        legend = self._legend(names, styles, latest, width)
        return Text("\n").join([legend, fig.render(width, plot_height)])

    def _clock_axis(self, view: TrendView, history: Mapping[str, np.ndarray] | None, t_new: float,
                    first: float, per_column: float, columns: int) -> Ticks:
        """Round clock times of the samples in view, or process time as H:MM:SS
        where the clock is not known for all of them."""
        t_first = t_new + first  # the left-most column's process time
        clock = self._clock_known(view, history if history is not None and len(history["t"]) else None)
        if clock is not None:
            return clock_ticks(clock, t_first, per_column, columns)
        return process_ticks(t_first, per_column, columns)

    def _ghost_curves(self, t_new: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The ghost's signals of this plot as (time relative to the newest sample,
        value in the unit shown)."""
        run, view = self.view.ghost, self.view
        if run is None:
            return {}
        x = run.t + view.ghost_start - t_new
        return {n: (x, run.signals[n] * view.scale(n).factor) for n in view.names if n in run.signals}

    def _y_range(self, view: TrendView, history: Mapping[str, np.ndarray] | None,
                 ghost: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> tuple[float, float]:
        """What the y axis must hold: the data in view (autoscale), else 0..full scale."""
        factor = view.scale(view.names[0]).factor
        if not view.autoscale:
            return 0.0, factor
        # The time range in view, at the columns of the last drawing (the y labels'
        # width decides them: the same at the same size).
        span = x_axis(view.window, self.columns, -view.offset)
        lo, hi = span.first, -view.offset
        parts = []
        if history is not None and len(history["t"]):
            t = history["t"]
            pick = visible(t - t[-1], lo, hi)
            parts += [history[n][pick] * view.scale(n).factor for n in view.names]
        for gx, gy in ghost.values():
            parts.append(gy[visible(gx, lo, hi)])
        values = np.concatenate(parts) if parts else np.zeros(0)
        if not len(values):
            return 0.0, factor
        return float(values.min()), float(values.max())

    def _legend(self, names: list[str], styles: Mapping[str, TraceStyle],
                latest: Mapping[str, float], width: int) -> Text:
        """Each signal's name and value at the view's right edge, in its colour (or
        after its marker without colour); shorter forms while the row is too
        narrow, and never wider than the row (a wrapped legend would push the plot
        down a row)."""
        view = self.view
        unit = view.unit
        decimals = 3 if not unit else 2
        ghost = f"ghost {view.ghost.name}" if view.ghost is not None else ""
        parts: list[tuple[str, str]] = []
        gap = " "
        for form in LEGEND_FORMS:
            gap = "  " if form.wide else " "
            parts = []
            for name in names:
                label = name.replace("ref", "r") if form.short else name
                value = f"{latest[name]:.{decimals}f}" if name in latest else ""
                if form.tight and value.startswith("0."):
                    value = value[1:]  # .614
                style = styles[name]
                marker = "" if style.color is not None else style.marker + ("" if form.tight else " ")
                parts.append((f"{marker}{label} {value}".rstrip(), style.rich))
            if form.unit and unit:
                parts.append((unit, ""))
            if form.ghost and ghost:
                parts.append((ghost, "dim"))
            if sum(len(p) for p, _ in parts) + len(gap) * (len(parts) - 1) <= width:
                break
        text = Text(no_wrap=True, overflow="crop")
        for n, (part, rich_style) in enumerate(parts):
            if text.cell_len + len(gap) * bool(n) + len(part) > width:
                break  # whole entries only: a cut value would read as another
            if n:
                text.append(gap)
            text.append(part, rich_style)
        return text

    def on_click(self, event: events.Click) -> None:
        self.post_message(ActionRequested(f"plot_type({self.which!r})"))
