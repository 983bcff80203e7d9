"""The widget every plot of the interface is drawn in (issue 43): a `Figure`
(plot_raster.py) rendered at the widget's content size, the trends on Main, the
plots of Identify and Design and the Apply preview alike.

A figure's ticks are laid out for the size it was drawn at; a plot whose size
changes afterwards (a resize, the Design screen's `v` showing its plots, a short
terminal giving the Nyquist plot's rows to the step plot) has its `relayout`
called to draw it again for the new size: drawn with the old ticks, an 80x24
step plot read "1" and "0" on 8 rows, laid out for 5."""

from __future__ import annotations

from typing import Any, Callable

from rich.text import Text
from textual.widget import Widget

from quadtank_tui.ui.widgets.plot_raster import Figure


class PlotView(Widget):
    """A Figure drawn at the size the layout gives it (inside its border)."""

    DEFAULT_CSS = """
    PlotView {
        width: 1fr;
        height: 1fr;
    }
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.figure = Figure()
        #: What draws the figure again for a new size (None: it is drawn at render time).
        self.relayout: Callable[[], None] | None = None

    def on_resize(self) -> None:
        if self.relayout is not None:
            self.call_after_refresh(self.relayout)

    @property
    def canvas(self) -> tuple[int, int]:
        """(columns, rows) of the figure's canvas at the present size."""
        return self.figure.canvas_size(self.content_size.width, self.content_size.height)

    def render(self) -> Text:
        return self.figure.render(self.content_size.width, self.content_size.height)
