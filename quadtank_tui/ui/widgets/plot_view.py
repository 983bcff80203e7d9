"""The widget every plot of the interface is drawn in (issue 43): a `Figure`
(plot_raster.py) rendered at the widget's content size, the trends on Main, the
plots of Identify and Design and the Apply preview alike."""

from __future__ import annotations

from typing import Any

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

    @property
    def canvas(self) -> tuple[int, int]:
        """(columns, rows) of the figure's canvas at the present size."""
        return self.figure.canvas_size(self.content_size.width, self.content_size.height)

    def render(self) -> Text:
        return self.figure.render(self.content_size.width, self.content_size.height)
