"""The small plots of Identify and Design (issues 28, 43): values read back off
the drawn plot, round ticks, the model over the measurement with both in sight,
and the colour of each series the same in the plot and in the legend of its
title."""

from __future__ import annotations

import io
import re
from typing import Any

import numpy as np
import pytest
from rich.console import Console
from rich.segment import Segment
from rich.style import Style as RichStyle
from rich.text import Text

from uikit import make_app
from quadtank_tui.ui.colours import BLUE, RED
from quadtank_tui.ui.screens.design import DesignScreen
from quadtank_tui.ui.widgets import plot_kit as kit
from quadtank_tui.ui.widgets.plot_kit import Series
from quadtank_tui.ui.widgets.plot_raster import Figure
from quadtank_tui.ui.widgets.plot_view import PlotView

Cell = tuple[str, RichStyle]
RGB = tuple[int, int, int]


def cells_of(text: Text, width: int) -> list[list[Cell]]:
    console = Console(width=width, color_system="truecolor", file=io.StringIO())
    lines = Segment.split_lines(console.render(text))
    return [[(ch, seg.style or RichStyle()) for seg in line for ch in seg.text] for line in lines]


def rgb(style: RichStyle) -> RGB | None:
    if style.color is None or style.color.is_default:
        return None
    r, g, b = style.color.get_truecolor()
    return (r, g, b)


def braille(ch: str) -> bool:
    return 0x2801 <= ord(ch) <= 0x28FF


def colours_drawn(rows: list[list[Cell]]) -> set[RGB]:
    return {c for row in rows for ch, st in row if braille(ch) and (c := rgb(st)) is not None}


def y_labels(rows: list[list[Cell]]) -> list[tuple[int, str]]:
    text = ["".join(ch for ch, _ in r) for r in rows]
    return [(n, m.group(1)) for n, line in enumerate(text) if (m := re.match(r"^\s*(-?\d+(?:\.\d+)?)\s*┤", line))]


def value_of_row(rows: list[list[Cell]], row: int) -> float:
    labelled = y_labels(rows)
    (r0, v0), (r1, v1) = (labelled[0][0], float(labelled[0][1])), (labelled[-1][0], float(labelled[-1][1]))
    return v0 + (row - r0) * (v1 - v0) / (r1 - r0)


def rows_of(rows: list[list[Cell]], colour: RGB, column: int | None = None) -> list[int]:
    return [n for n, row in enumerate(rows)
            if any(braille(ch) and rgb(st) == colour for j, (ch, st) in enumerate(row)
                   if column is None or j == column)]


def legend_colours(title: Any) -> dict[str, RGB]:
    """Each legend entry's label -> its colour, from a title's spans (a plot's
    border title as Textual keeps it: Content)."""
    if isinstance(title, PlotView):
        title = title._border_title
    out = {}
    for span in title.spans:
        colour = RichStyle.parse(str(span.style)).color
        assert colour is not None
        r, g, b = colour.get_truecolor()
        out[title.plain[span.start:span.end].split(" ", 1)[1]] = (r, g, b)
    return out


def test_round_ticks_share_their_decimals() -> None:
    assert kit.round_ticks(0.605, 0.655, 6) == ([0.61, 0.62, 0.63, 0.64, 0.65],
                                                ["0.61", "0.62", "0.63", "0.64", "0.65"])
    assert kit.round_ticks(0.0, 1795.5, 6)[1] == ["0", "500", "1000", "1500"]
    assert kit.round_ticks(-0.5, 20.5, 8, whole=True)[1] == ["0", "5", "10", "15", "20"]
    assert kit.round_ticks(-0.5, 3.5, 20, whole=True)[1] == ["0", "1", "2", "3"]  # never 0.5 lags


def test_values_read_back_and_the_model_over_the_measurement() -> None:
    t = np.linspace(0.0, 100.0, 400)
    measured = 0.62 + 0.03 * np.sin(t / 10)
    model = measured + 0.004  # a tenth of a row apart at most: drawn on the same cells
    meas_st, model_st = kit.styles([Series("y1", BLUE), Series("model", RED)], dark=True, no_color=False)
    fig = Figure()
    kit.draw(fig, t, measured, meas_st)
    kit.draw(fig, t, model, model_st)
    kit.axes(fig, (0.0, 100.0), (0.58, 0.66), 60, 20)
    rows = cells_of(fig.render(60, 20), 60)
    assert [v for _, v in y_labels(rows)] == ["0.66", "0.64", "0.62", "0.60", "0.58"]  # top down
    drawn = colours_drawn(rows)
    assert drawn == {BLUE.dark, RED.dark}  # both curves show
    blue = sum(len(rows_of(rows, BLUE.dark, j)) > 0 for j in range(60))
    red = sum(len(rows_of(rows, RED.dark, j)) > 0 for j in range(60))
    assert blue > 20 and red > 20 and blue + red >= 55  # the cells they share take turns
    # the measured curve read back where sin is at its top (t = 5 pi, column of x)
    both = [j for j in range(60) if rows_of(rows, BLUE.dark, j) or rows_of(rows, RED.dark, j)]
    first_col, last_col = min(both), max(both)
    col = first_col + round(5 * np.pi / 100 * (last_col - first_col))
    top = min(rows_of(rows, BLUE.dark, col) + rows_of(rows, RED.dark, col))
    assert value_of_row(rows, top) == pytest.approx(0.65, abs=0.008)


def test_the_legend_has_the_colours_drawn_and_markers_without_colour() -> None:
    drawn = kit.styles([Series("model", RED, dotted=True), Series("y1", BLUE)], dark=False, no_color=False)
    assert legend_colours(kit.legend(drawn)) == {"model": RED.light, "y1": BLUE.light}
    assert kit.legend(drawn).plain == "┈ model ━ y1"
    plain = kit.styles([Series("model", RED, dotted=True), Series("y1", BLUE), Series("y2", RED)],
                       dark=True, no_color=True)
    assert kit.legend(plain).plain == "· model * y1 + y2"
    assert not kit.legend(plain).spans or all(not str(s.style) for s in kit.legend(plain).spans)


def plot_cells(plot: PlotView) -> list[list[Cell]]:
    return cells_of(plot.render(), plot.content_size.width)


async def test_design_plots_match_their_legends_and_read_back(engine: Any) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("d")
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        screen = app.screen
        assert isinstance(screen, DesignScreen)
        await pilot.press("2")  # the 2x2 design chooses both loops
        for _ in range(3):
            await pilot.app.workers.wait_for_complete()
            await pilot.pause()
        dark = app.current_theme.dark
        for which in ("#nyquist", "#response"):
            plot = screen.query_one(which, PlotView)
            legend = legend_colours(plot)
            drawn = colours_drawn(plot_cells(plot))
            assert set(legend.values()) <= drawn, (which, plot.border_title, drawn)
        steps = screen.query_one("#response", PlotView)
        assert set(legend_colours(steps)) == {"y1", "y2", "r"}
        rows = plot_cells(steps)
        assert legend_colours(steps)["y1"] == BLUE.rgb(dark)
        # both loops settle on the reference: the right-most column reads 1.0
        last = max(j for j in range(len(rows[0])) if rows_of(rows, BLUE.rgb(dark), j))
        for colour in (BLUE.rgb(dark), RED.rgb(dark)):
            (row,) = rows_of(rows, colour, last) or rows_of(rows, colour, last - 1)
            assert value_of_row(rows, row) == pytest.approx(1.0, abs=0.1)
        await pilot.press("b")  # |S| |T| with the Ms line, and the load step
        await pilot.pause()
        bode = screen.query_one("#nyquist", PlotView)
        assert set(legend_colours(bode)) == {"|S|", "|T|", "Ms"}
        assert set(legend_colours(bode).values()) <= colours_drawn(plot_cells(bode))



def check_identify_plots(screen: Any) -> None:
    """After a fit (test_identify_screen's, which this saves running twice): the
    output plot and the residuals drawn in the colours their titles' legends give."""
    top, low = screen.query_one("#outputs", PlotView), screen.query_one("#lower", PlotView)
    dark = screen.app.current_theme.dark
    assert legend_colours(top) == {"y1": BLUE.rgb(dark), "model": RED.rgb(dark)}
    rows = plot_cells(top)
    # nothing drawn in a colour the legend does not name; the measurement whole
    assert BLUE.rgb(dark) in colours_drawn(rows) <= set(legend_colours(top).values())
    assert all(re.fullmatch(r"0\.\d\d", v) for _, v in y_labels(rows))  # 0.58 0.60 ...
    lags = plot_cells(low)
    assert set(legend_colours(low).values()) == colours_drawn(lags)  # stems and the band
    axis = next(line for r in reversed(lags) if re.search(r"\d", line := "".join(c for c, _ in r)))
    assert re.findall(r"-?\d+(?:\.\d+)?", axis) == ["0", "5", "10", "15", "20", "25"]


def test_every_hue_of_the_palette_is_readable_on_its_theme_background() -> None:
    """WCAG 3:1 for graphics, for the hues Identify and Design draw with too (the
    trends' signals are checked in test_trend_view)."""
    from textual.color import Color
    from textual.theme import BUILTIN_THEMES

    from quadtank_tui.ui import colours
    from quadtank_tui.ui.widgets.trend_style import contrast

    hues = [h for h in vars(colours).values() if isinstance(h, colours.Hue)]
    assert len(hues) == 7
    for name, theme in BUILTIN_THEMES.items():
        if name.startswith(("ansi", "textual-ansi")):
            continue
        surface = Color.parse(theme.to_color_system().generate()["surface"]).rgb
        for hue in hues:
            assert contrast(hue.rgb(theme.dark), surface) >= 3.0, (name, hue.name)


@pytest.mark.parametrize("size", [(120, 40), (80, 24)])
async def test_the_design_preview_draws_prediction_and_simulation_and_reads_back(
        engine: Any, size: tuple[int, int]) -> None:
    """Apply's preview (issue 23) follows issue 28's rules: the legend names the
    colours drawn (no colour in words), prediction and simulation both visible
    where they agree, at least three round x ticks, the simulated level read off
    the right-most column where the simulation ended; and at 80x24 Apply and
    Cancel are on the screen."""
    from quadtank_tui.core.design.mimo import design_2x2, model_in_use
    from quadtank_tui.core.parameters import PRESET
    from quadtank_tui.app.design import PreviewPlan
    from quadtank_tui.ui.windows.design_preview import DesignPreviewWindow

    G = model_in_use(PRESET)
    pair = tuple(loop.controller for loop in design_2x2(G, h=1.0).loops)
    plant = PRESET.process_plant()
    levels = PRESET.process_levels()
    op = plant.steady_inputs([levels[0], levels[1], None, None])
    request = PreviewPlan(plant, tuple(op.x), tuple(op.u), pair, 1.0, G, (1.0, 1.0), window=300.0)
    app = make_app(engine)
    async with app.run_test(size=size) as pilot:
        pilot.app.push_screen(DesignPreviewWindow(request))
        await pilot.pause()
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        window = pilot.app.screen
        assert isinstance(window, DesignPreviewWindow) and window.result is not None
        dark = app.current_theme.dark
        what = str(window.query_one("#preview-what").render())
        assert not re.search(r"\b(blue|red)\b", what), what
        for step in window.result.steps:
            plot = window.query_one(f"#preview-loop{step.loop}", PlotView)
            assert legend_colours(plot) == {"simulated": RED.rgb(dark), "predicted": BLUE.rgb(dark)}
            rows = plot_cells(plot)
            assert colours_drawn(rows) == {RED.rgb(dark), BLUE.rgb(dark)}
            axis = next(line for r in reversed(rows) if re.search(r"\d", line := "".join(c for c, _ in r)))
            assert len(re.findall(r"\d+", axis)) >= 3, axis
            last = max(j for j in range(len(rows[0])) if rows_of(rows, RED.rgb(dark), j))
            row = rows_of(rows, RED.rgb(dark), last)[-1]
            labelled = y_labels(rows)
            per_row = abs(float(labelled[-1][1]) - float(labelled[0][1])) / max(1, labelled[-1][0] - labelled[0][0])
            assert value_of_row(rows, row) == pytest.approx(float(step.simulated[-1]), abs=1.5 * per_row)
        for button in ("#apply", "#cancel"):
            assert window.query_one(button).region.bottom <= size[1] - 1  # above the footer
