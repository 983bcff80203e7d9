"""A line is a line (issue 43): read back off the drawn plot, dot by dot, that a
step is one connected stroke, that two series in the same cells are both found,
that the 1/Ms circle is round, and that a plot too small says so with its
figures.  The dots are decoded from the braille characters drawn (Unicode's
bit order, written out here), not by the code that drew them."""

from __future__ import annotations

import io

import numpy as np
import pytest
from rich.console import Console
from rich.segment import Segment
from rich.style import Style as RichStyle
from rich.text import Text

from uikit import make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.colours import BLUE, ORANGE, RED
from quadtank_tui.ui.screens.design_plots import DesignPlots, draw_nyquist
from quadtank_tui.ui.widgets import plot_kit as kit
from quadtank_tui.ui.widgets.plot_kit import Series
from quadtank_tui.ui.widgets.plot_raster import Figure, Pen
from quadtank_tui.ui.widgets.trend_style import DARK
from quadtank_tui.ui.widgets.trends import Trend

RGB = tuple[int, int, int]
#: Unicode braille: bit of the dot at (row from the top, column) of a cell.
BIT = {(0, 0): 0x01, (1, 0): 0x02, (2, 0): 0x04, (3, 0): 0x40, (0, 1): 0x08, (1, 1): 0x10, (2, 1): 0x20,
       (3, 1): 0x80}


def cells(text: Text, width: int) -> list[list[tuple[str, RGB | None]]]:
    console = Console(width=width, color_system="truecolor", file=io.StringIO())
    out = []
    for line in Segment.split_lines(console.render(text)):
        row = []
        for seg in line:
            style = seg.style or RichStyle()
            colour = None
            if style.color is not None and not style.color.is_default:
                t = style.color.get_truecolor()
                colour = (t.red, t.green, t.blue)
            row += [(ch, colour) for ch in seg.text]
        out.append(row)
    return out


def dots(rows: list[list[tuple[str, RGB | None]]], colour: RGB | None = None) -> set[tuple[int, int]]:
    """Every braille dot drawn (in cells of `colour`, or any), as (x, y) with y down."""
    found = set()
    for r, row in enumerate(rows):
        for col, (ch, rgb) in enumerate(row):
            code = ord(ch) - 0x2800
            if not 0 < code <= 0xFF or (colour is not None and rgb != colour):
                continue
            for (dr, dc), bit in BIT.items():
                if code & bit:
                    found.add((2 * col + dc, 4 * r + dr))
    return found


def connected(points: set[tuple[int, int]]) -> bool:
    """All dots one 8-connected piece."""
    todo, seen = [next(iter(points))], set()
    while todo:
        p = todo.pop()
        if p in seen:
            continue
        seen.add(p)
        todo += [(p[0] + dx, p[1] + dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if (p[0] + dx, p[1] + dy) in points]
    return seen == points


def test_a_step_is_one_connected_vertical_stroke() -> None:
    """A level sampled every second steps from 10 to 12 between two samples: the
    dots drawn are one piece, and the rise is a stroke at most two dots wide with
    a dot on every dot row between the levels."""
    t = np.arange(0.0, 200.0, 1.0)
    y = np.where(t < 100, 10.0, 12.0)
    fig = Figure(xlim=(0.0, 199.0), ylim=(9.0, 13.0), yticks=[(10.0, "10"), (12.0, "12")])
    fig.line(t, y, Pen(BLUE.dark))
    rows = cells(fig.render(60, 14), 60)
    drawn = dots(rows, BLUE.dark)
    assert connected(drawn)
    low, high = max(y for _, y in drawn), min(y for _, y in drawn)
    between = {(x, yy) for x, yy in drawn if high < yy < low}
    assert {yy for _, yy in between} == set(range(high + 1, low))
    assert max(x for x, _ in between) - min(x for x, _ in between) <= 1
    assert low - high >= 4 * 12 * 2 / 4 - 2  # 2 units of 4 on 12 rows: about 24 dots


def test_two_series_in_the_same_cells_are_both_found() -> None:
    """y1 settled on ref1 (the same values): each shows in its own colour along
    the line; y2 a hair below y1 shares their cells too and still shows."""
    t = np.linspace(-300.0, 0.0, 3000)
    fig = Figure(xlim=(-300.0, 0.0), ylim=(9.0, 14.0), yticks=[(10.0, "10"), (12.0, "12")])
    fig.line(t, np.full(len(t), 12.38), Pen(DARK["ref1"], dashed=True))
    fig.line(t, np.full(len(t), 12.38), Pen(DARK["y1"]))
    fig.line(t, np.full(len(t), 12.30), Pen(DARK["y2"]))
    rows = cells(fig.render(80, 12), 80)
    for name in ("y1", "ref1", "y2"):
        mine = [col for row in rows for col, (ch, rgb) in enumerate(row) if rgb == DARK[name] and ch != " "]
        assert len(mine) >= 8, name
        assert max(mine) - min(mine) > 60, name  # along the whole line, not at one end
    # NO_COLOR: markers take the cells in turn the same way
    plain = Figure(xlim=(-300.0, 0.0), ylim=(9.0, 14.0), yticks=[(10.0, "10")])
    plain.line(t, np.full(len(t), 12.38), Pen(None, "o", dashed=True))
    plain.line(t, np.full(len(t), 12.38), Pen(None, "*"))
    text = plain.render(80, 12).plain
    assert text.count("o") >= 8 and text.count("*") >= 30


def test_the_nyquist_circle_is_round_at_every_size() -> None:
    """The 1/Ms circle's dots span as many dots across as up (a dot of a 1:2 cell
    is square), at 120x40's and 80x24's plot sizes."""
    th = np.linspace(0, 2 * np.pi, 50)
    plots = DesignPlots(L=-0.5 + 0.2 * np.exp(1j * th), w=np.ones(2), S=np.ones(2), T=np.ones(2),
                        load=None, steps={}, ms=1.6)  # type: ignore[arg-type]  # only the Nyquist plot is drawn

    class Sized:  # the widget's part that draw_nyquist reads
        def __init__(self, w: int, h: int) -> None:
            self.figure, self.border_title = Figure(), None
            self.content_size = type("S", (), {"width": w, "height": h})()

    for w, h in ((56, 16), (74, 12), (40, 20)):
        plot = Sized(w, h)
        draw_nyquist(plot, plots, True, False)  # type: ignore[arg-type]
        rows = cells(plot.figure.render(w, h), w)
        circle = dots(rows, ORANGE.dark)
        xs, ys = [x for x, _ in circle], [y for _, y in circle]
        across, up = max(xs) - min(xs), max(ys) - min(ys)
        assert up > 8 and abs(across - up) <= 0.08 * up + 2, (w, h, across, up)


def test_a_plot_too_small_says_so_with_its_figures() -> None:
    fig = Figure(min_rows=7, too_small="Nyquist: Ms 1.41")
    fig.line([0, 1], [0, 1], Pen(BLUE.dark))
    text = fig.render(40, 6).plain
    assert "Nyquist: Ms 1.41" in text and "needs" in text
    assert not any(0x2800 < ord(ch) <= 0x28FF for ch in text)


def test_the_legend_and_the_model_drawn_last() -> None:
    """The kit's model series is drawn over the measurement: listed last."""
    meas, model = kit.styles([Series("y1", BLUE), Series("model", RED)], dark=True, no_color=False)
    assert kit.legend([meas, model]).plain == "━ y1 ━ model"


async def test_main_after_a_step_shows_all_four_traces_in_cm(engine: object) -> None:
    """The issue's case: Automatic, units cm, ref1 stepped down by 0.1, the lower
    trend at type 6 (y1 y2 ref1 ref2): each of the four in its colour on the plot."""
    engine.submit(c.SetState("Run"))  # type: ignore[attr-defined]
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("a")
        engine.run_for(100.0)  # type: ignore[attr-defined]
        engine.submit(c.NudgeMean(1, -0.1))  # type: ignore[attr-defined]
        engine.run_for(400.0)  # type: ignore[attr-defined]
        await pilot.press("u")
        lower = app.main.query_one("#lower", Trend)
        for _ in range(6):
            if lower.view.names == ["y1", "y2", "ref1", "ref2"]:
                break
            await pilot.press("G")
        assert lower.view.names == ["y1", "y2", "ref1", "ref2"]
        app.main.refresh_view()
        await pilot.pause()
        rows = cells(lower.render(), lower.content_size.width)
    assert "cm" in "".join(ch for ch, _ in rows[0])
    for name in ("y1", "y2", "ref1", "ref2"):
        drawn = {col for row in rows[1:] for col, (ch, rgb) in enumerate(row)
                 if rgb == DARK[name] and 0x2800 < ord(ch) <= 0x28FF}
        assert len(drawn) >= 5, name
        assert max(drawn) >= lower.content_size.width - 12, name  # still drawn at the newest samples


@pytest.mark.parametrize("n", [20_000])
def test_drawing_a_long_trace_is_quick(n: int) -> None:
    """Every sample in view is joined (none dropped to decimation); 4 traces of
    20,000 samples take well under the UI timer's tick."""
    import time

    t = np.linspace(-1800.0, 0.0, n)
    fig = Figure(xlim=(-1800.0, 0.0), ylim=(-1.0, 1.0), yticks=[(0.0, "0")])
    rng = np.random.default_rng(1)
    for k in range(4):
        fig.line(t, np.sin(t / 50 + k) * 0.8 + 0.05 * rng.standard_normal(n), Pen(BLUE.dark))
    start = time.process_time()
    fig.render(118, 18)
    assert time.process_time() - start < 0.25


async def test_a_plot_is_laid_out_again_for_its_new_size() -> None:
    """A figure's ticks are for the size it was drawn at: a resize calls the
    plot's relayout, which draws it for the size it has now."""
    from textual.app import App, ComposeResult

    from quadtank_tui.ui.widgets.plot_view import PlotView

    sizes: list[int] = []

    class One(App[None]):
        def compose(self) -> ComposeResult:
            yield PlotView()

    app = One()
    async with app.run_test(size=(60, 20)) as pilot:
        plot = app.query_one(PlotView)

        def draw() -> None:
            sizes.append(plot.content_size.height)
            kit.axes(plot.figure, (0.0, 100.0), (-0.1, 1.0), plot.content_size.width, plot.content_size.height)

        plot.relayout = draw
        await pilot.resize_terminal(60, 12)
        await pilot.pause()
        await pilot.pause()
        assert sizes and sizes[-1] == 12
        text = plot.render().plain
        labels = [line.split("┤")[0].strip() for line in text.splitlines() if "┤" in line]
        assert len(labels) >= 3, text
