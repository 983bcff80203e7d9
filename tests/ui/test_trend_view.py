"""The trends as a student reads them (issue 17, "What a modern terminal tool is
expected to have"): a legend in the curves' own colours with each signal's
latest value, readable themes and NO_COLOR, normalized or physical units, a
round time axis, scrolling back while paused, and a saved run as a ghost.

Everything is read back off what was drawn: the rendered segments of the trend
(characters and their styles), its tick labels and the rows and columns they are
on, through the app as a user drives it on a manual-clock engine.
"""

from __future__ import annotations

import io
import math
import re
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console
from rich.segment import Segment
from rich.style import Style
from textual.color import Color
from textual.theme import BUILTIN_THEMES

from bursts import burst, pause_until
from uikit import Recording, make_app, plot_text
from test_repaint_cost import Wire, paused_app, ticks
from test_trust import read_constant

from quadtank_tui.engine import commands as c
from quadtank_tui.files.log_writer import format_header, format_row
from quadtank_tui.ui.ghost.window import GhostWindow
from quadtank_tui.ui.widgets.trend_style import DARK, GHOST_FADE, LIGHT, MARKERS, blend, contrast
from quadtank_tui.ui.plot_axes import XDOTS, x_axis
from quadtank_tui.ui.widgets.trends import Trend

Cell = tuple[str, Style]


def cells(trend: Trend) -> list[list[Cell]]:
    """The trend as drawn: one list of (character, style) per row."""
    console = Console(width=trend.size.width, color_system="truecolor", file=io.StringIO())
    lines = Segment.split_lines(console.render(trend.render()))
    return [[(ch, seg.style or Style()) for seg in line for ch in seg.text] for line in lines]


def braille(ch: str) -> bool:
    return 0x2801 <= ord(ch) <= 0x28FF


def rgb(style: Style) -> tuple[int, int, int] | None:
    if style.color is None or style.color.is_default:
        return None
    r, g, b = style.color.get_truecolor()
    return (r, g, b)


def legend_colour(rows: list[list[Cell]], name: str) -> tuple[int, int, int] | None:
    """The colour of `name` in the legend (the first row)."""
    text = "".join(ch for ch, _ in rows[0])
    at = re.search(rf"\b{name}\b", text)
    assert at, text
    return rgb(rows[0][at.start()][1])


def row_of(rows: list[list[Cell]], colour: tuple[int, int, int]) -> set[int]:
    """The rows where the curve of `colour` is drawn."""
    return {n for n, row in enumerate(rows) if any(braille(ch) and rgb(st) == colour for ch, st in row)}


def label_value(rows: list[list[Cell]], row: int) -> float:
    """The y value of a row, read off the labels as a person would."""
    plot = "\n".join("".join(ch for ch, _ in r) for r in rows)
    lines = plot.splitlines()
    labelled = [(n, float(m.group(1))) for n, line in enumerate(lines)
                if (m := re.match(r"^\s*(-?\d+(?:\.\d+)?)\s*┤", line))]
    (r0, v0), (r1, v1) = labelled[0], labelled[-1]
    return v0 + (row - r0) * (v1 - v0) / (r1 - r0)


async def running_app(engine: Recording, size: tuple[int, int], seconds: float = 200.0,
                      keys: tuple[str, ...] = (), settings: dict[str, Any] | None = None) -> Any:
    """The app after `seconds` of the default session (Manual, u1 = u2 = 0.3)."""
    if settings:
        engine.submit(c.SetParams(settings))
    engine.submit(c.SetState("Run"))
    engine.run_for(seconds)
    return make_app(engine)


# --- 1. legend colours are the curves' colours; themes; NO_COLOR ------------------------------

@pytest.mark.parametrize("theme", ["textual-dark", "textual-light"])
async def test_the_legend_has_the_colour_of_its_curve(engine: Recording, theme: str) -> None:
    app = await running_app(engine, (120, 40), settings={"REFERENCE TWO.Mean": 0.5})  # u2 = 0.5, u1 = 0.3
    async with app.run_test(size=(120, 40)) as pilot:
        app.theme = theme
        app.main.refresh_view()
        await pilot.pause()
        rows = cells(app.main.query_one("#upper", Trend))
    table = DARK if theme == "textual-dark" else LIGHT
    for name, value in (("u1", 0.3), ("u2", 0.5)):
        colour = legend_colour(rows, name)
        assert colour == table[name]
        drawn = row_of(rows, colour)
        assert len(drawn) == 1, (name, drawn)
        assert abs(label_value(rows, drawn.pop()) - value) < 0.05, name
    legend = "".join(ch for ch, _ in rows[0])
    assert "u1 0.300" in legend and "u2 0.500" in legend  # the latest values


def test_every_colour_is_readable_on_its_theme_background() -> None:
    """WCAG 3:1 for graphics, against the plot's background (the theme's surface)."""
    checked = 0
    for name, theme in BUILTIN_THEMES.items():
        if name.startswith(("ansi", "textual-ansi")):
            continue  # the terminal's own colours: not ours to choose
        surface = Color.parse(theme.to_color_system().generate()["surface"]).rgb
        for signal, colour in (DARK if theme.dark else LIGHT).items():
            assert contrast(colour, surface) >= 3.0, (name, signal, contrast(colour, surface))
        checked += 1
    assert checked >= 15


async def test_no_color_writes_no_colour_and_tells_the_curves_apart_by_marker(
        engine: Recording, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NO_COLOR", "1")
    engine.submit(c.SetParams({"REFERENCE TWO.Mean": 0.5}))
    engine.submit(c.SetState("Run"))
    engine.run_for(100.0)
    engine.submit(c.SetState("Pause"))
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        wire = Wire(app)
        await ticks(app, pilot, engine, 0.5)
        app.main.refresh_view()
        await pilot.pause()
        trend = app.main.query_one("#upper", Trend)
        rows = cells(trend)
        await pilot.press("u")  # a view change after the first frame: written too
        await ticks(app, pilot, engine, 0.2)
    written = "".join(wire.updates)
    assert written, "the screen was drawn"
    sgr = [p for m in re.finditer(r"\x1b\[([0-9;]*)m", written) for p in m.group(1).split(";") if p]
    colours = [p for p in sgr if p in ("38", "48") or 30 <= int(p) <= 37 or 40 <= int(p) <= 47
               or 90 <= int(p) <= 107]
    assert not colours, f"colour codes in the output: {sorted(set(colours))}"
    assert all(st.color is None and st.bgcolor is None for row in rows for _, st in row)
    legend = "".join(ch for ch, _ in rows[0])
    assert f"{MARKERS[0]} u1 0.300" in legend and f"{MARKERS[1]} u2 0.500" in legend
    plot = ["".join(ch for ch, _ in row).partition("┤")[2] for row in rows[1:]]
    u1_rows = [n for n, line in enumerate(plot) if MARKERS[0] in line]
    u2_rows = [n for n, line in enumerate(plot) if MARKERS[1] in line]
    assert len(u1_rows) == 1 and len(u2_rows) == 1 and u2_rows[0] < u1_rows[0]


async def test_a_legend_never_wraps_into_the_plot(engine: Recording, monkeypatch: pytest.MonkeyPatch) -> None:
    """NO_COLOR at 80x24, four signals and their markers: 40 characters in 38
    wrapped the last value onto the plot's first row, and every row shifted."""
    monkeypatch.setenv("NO_COLOR", "1")
    app = await running_app(engine, (80, 24))
    async with app.run_test(size=(80, 24)) as pilot:
        app.main.refresh_view()
        await pilot.pause()
        lower = app.main.query_one("#lower", Trend)
        lines = lower.render().plain.splitlines()
        width, height = lower.size.width, lower.size.height
    assert len(lines) == height and all(len(line) <= width for line in lines)
    legend = lines[0]
    assert [e[:3] for e in legend.split()[::2]] == ["*y1", "+y2", "or1", "xr2"], legend
    assert re.match(r"^\s*0\.\d+┤", lines[1]), lines[1]  # the plot starts on the second row


# --- 2. units --------------------------------------------------------------------------------

@pytest.mark.parametrize("size", [(80, 24), (100, 30), (120, 40)])
async def test_physical_units_read_back_volts_and_centimetres(engine: Recording, size: tuple[int, int]) -> None:
    app = await running_app(engine, size)
    async with app.run_test(size=size) as pilot:
        app.main.refresh_view()
        await pilot.press("u")
        upper = app.main.query_one("#upper", Trend)
        plot = plot_text(upper)
        value, half_row = read_constant(plot)
        assert abs(value - 3.0) <= half_row, plot  # u = 0.300 of 10 V
        labels = [float(m.group(1)) for line in plot.splitlines() if (m := re.match(r"^\s*(\d+\.\d+)┤", line))]
        assert len(labels) >= 2 and all(abs(v * 100 - round(v * 100)) < 1e-9 for v in labels), labels
        assert plot.splitlines()[0].startswith("u1 3.00  u2 3.00  V")
        assert "u V" in str(upper.border_subtitle)
        lower = app.main.query_one("#lower", Trend)
        legend = lower.render().plain.splitlines()[0]
        y1 = engine.snapshot().y[0]
        assert f"y1 {y1 * 20.0:.2f}" in legend and legend.rstrip().endswith("cm")  # 1.0 is 20 cm
        await pilot.press("u")
        assert abs(read_constant(plot_text(upper))[0] - 0.3) < 0.003


# --- 3. the time axis ------------------------------------------------------------------------

def test_time_ticks_fall_on_the_columns_of_their_times() -> None:
    for window in (120.0, 300.0, 600.0, 1800.0):
        for columns in (31, 34, 50, 73, 113):
            axis = x_axis(window, columns)
            per = axis.per_column
            assert columns * per >= window and (columns - 1) * per <= 1.25 * window, (window, columns)
            assert axis.ticks[-1] == 0.0 and len(axis.ticks) >= 3
            assert axis.tick in (1, 2, 5, 10, 15, 20, 30, 60, 120, 300, 600)
            for tick in axis.ticks:
                f = (tick - axis.lo) / (axis.hi - axis.lo)
                tick_column = math.floor(0.5 + (columns - 1) * f)
                dot = math.floor(0.5 + (XDOTS * columns - 1) * f)
                assert dot // XDOTS == tick_column, (window, columns, tick)
                assert tick_column == columns - 1 + round(tick / per)


def read_time(plot: str, column: int) -> tuple[float, float]:
    """The time of a column, read off the x labels under their ticks, and half a
    column in seconds."""
    lines = plot.splitlines()
    axis = next(n for n, line in enumerate(lines) if "└" in line)
    ticks = [n for n, ch in enumerate(lines[axis]) if ch == "┬"]
    labels = lines[axis + 1]
    values = []
    for col in ticks:
        m = re.search(r"-?\d+", labels[max(0, col - 3):col + 3])
        assert m, (col, labels)
        values.append(float(m.group()))
    gaps = {b - a for a, b in zip(ticks, ticks[1:])}
    steps = {b - a for a, b in zip(values, values[1:])}
    assert len(gaps) == 1 and len(steps) == 1, (gaps, steps, labels)  # evenly spaced, round
    per_column = steps.pop() / gaps.pop()
    return values[-1] + (column - ticks[-1]) * per_column, per_column / 2


@pytest.mark.parametrize("size", [(80, 24), (100, 30), (120, 40)])
async def test_the_time_axis_is_round_and_reads_back_a_step(engine: Recording, size: tuple[int, int]) -> None:
    """u1 steps 0.3 -> 0.5 200 s before the newest sample: the step is read at -200 s."""
    engine.submit(c.SetState("Run"))
    engine.run_for(100.0)
    engine.submit(c.SetParams({"REFERENCE ONE.Mean": 0.5}))
    engine.run_for(200.0)
    app = make_app(engine)
    async with app.run_test(size=size) as pilot:
        app.main.refresh_view()
        await pilot.pause()
        plot = plot_text(app.main.query_one("#upper", Trend))
    lines = plot.splitlines()
    labels = lines[[n for n, line in enumerate(lines) if "└" in line][0] + 1].split()
    assert labels[-1] == "0" and all(float(v) % 10 == 0 for v in labels), labels
    # The newest sample is in the last column; the step is where u1 leaves its old row.
    high = [line.partition("┤")[2] for line in lines if "┤" in line]
    rows_with_curve = [n for n, line in enumerate(high) if any(braille(ch) for ch in line)]
    top = high[rows_with_curve[0]]
    start = plot.splitlines()[1 + rows_with_curve[0]].index("┤") + 1
    first = next(n for n, ch in enumerate(top) if braille(ch))
    value, half = read_time(plot, start + first)
    assert abs(value - (-200.0)) <= 2 * half + 1.0, (size, value, plot)


# --- 4. scrolling back while paused -------------------------------------------------------------

async def test_a_paused_trend_scrolls_back_and_end_returns(engine: Recording) -> None:
    engine.submit(c.SetState("Run"))
    engine.run_for(300.0)
    engine.submit(c.SetParams({"REFERENCE ONE.Mean": 0.6}))
    engine.run_for(300.0)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        app.main.refresh_view()
        await pilot.pause()
        upper = app.main.query_one("#upper", Trend)
        await pilot.press("left")  # running: it says why it does nothing
        assert app.main.trend_offset == 0.0 and "Pause first" in list(app._notifications)[-1].message
        engine.submit(c.SetState("Pause"))
        await burst(pilot, "left", "left", "left")  # 150 s each at 120x40
        t_new = engine.snapshot().t
        assert app.main.trend_offset == 450.0  # 150 s a press: half the window, 5 labels of 30 s
        assert t_new == pytest.approx(600.0)
        assert upper.border_title == "viewing t = 0-150 s, End to return"  # nothing before 0
        plot = plot_text(upper)
        assert plot.splitlines()[0].startswith("u1 0.300")  # the value at the view's right edge
        assert plot.splitlines()[-1].split()[-1] == "-450"
        await burst(pilot, "right", "right")  # the view ends at t = 450 s
        assert upper.border_title == "viewing t = 150-450 s, End to return"
        assert plot_text(upper).splitlines()[0].startswith("u1 0.600")
        await pilot.press("end")
        assert upper.border_title == "live, t in s" and app.main.trend_offset == 0.0
        await burst(pilot, *["left"] * 10)  # not so far back that nothing is in view
        assert app.main.trend_offset == 450.0


async def test_a_scrolled_paused_screen_writes_nothing(engine: Recording) -> None:
    engine.submit(c.SetState("Run"))
    engine.run_for(600.0)
    engine.submit(c.SetState("Pause"))
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("left")
        await ticks(app, pilot, engine, 0.5)
        wire = Wire(app)
        await ticks(app, pilot, engine, 1.0)
    assert wire.bytes == 0, wire.updates[:1]


# --- 5. ghost traces ---------------------------------------------------------------------------

def write_log(path: Path, rows: int, u1: float, u2: float, tsamp: float = 1.0) -> None:
    from datetime import datetime

    body = "".join(format_row((0.6, 0.6, u1, u2)) for _ in range(rows))
    path.write_text(format_header(("y1", "y2", "u1", "u2"), tsamp, datetime(2026, 1, 5)) + body)


async def wait_for_ghost(pilot: Any, app: Any) -> None:
    await pause_until(pilot, lambda: app.main.ghost.run is not None, what="the ghost to be loaded")


async def test_a_ghost_run_is_drawn_dimmed_at_its_values_and_cleared(engine: Recording) -> None:
    logs = Path(engine.logs_dir)
    write_log(logs / "older.log", 50, 0.1, 0.1)
    write_log(logs / "yesterday.log", 400, 0.5, 0.6)  # the newest: the default
    engine.submit(c.LogOn())  # at t = 0: the ghost's first row goes there
    app = await running_app(engine, (120, 40))
    async with app.run_test(size=(120, 40)) as pilot:
        app.main.refresh_view()
        await pilot.press("b")
        assert isinstance(app.screen, GhostWindow)
        await pilot.press("enter")
        await wait_for_ghost(pilot, app)
        await pilot.pause()
        upper = app.main.query_one("#upper", Trend)
        rows = cells(upper)
        ghost = blend(DARK["u1"], Color.parse(app.theme_variables["surface"]).rgb, GHOST_FADE)
        drawn = row_of(rows, ghost)
        assert len(drawn) == 1
        value = label_value(rows, drawn.pop())
        assert abs(value - 0.5) < 1e-9, value  # on the row labelled 0.5 (0.1 a row)
        live = row_of(rows, DARK["u2"])  # u1 = u2 = 0.3 live: u2 drawn last, on top
        assert len(live) == 1 and abs(label_value(rows, live.pop()) - 0.3) < 1e-9
        assert "ghost yesterday.log" in "".join(ch for ch, _ in rows[0])
        assert "ghost yesterday.log" in str(upper.border_title)
        await pilot.press("B")
        assert app.main.ghost.run is None and not row_of(cells(upper), ghost)


async def test_a_ghost_aligned_at_a_chosen_time_and_at_logon(engine: Recording) -> None:
    logs = Path(engine.logs_dir)
    write_log(logs / "run.log", 50, 0.45, 0.6)  # 50 s
    engine.submit(c.SetState("Run"))
    engine.run_for(40.0)
    engine.submit(c.LogOn())
    engine.run_for(160.0)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        app.main.refresh_view()
        assert app.main.ghost.start == pytest.approx(40.0, abs=1e-9)  # the LogOn's process time
        await burst(pilot, "b", "tab", "tab", *"120", "enter")  # the list, the alignment, the time
        await wait_for_ghost(pilot, app)
        assert app.main.ghost.start == 120.0
        await pilot.pause()
        rows = cells(app.main.query_one("#upper", Trend))
        t_new = float(engine.history()["t"][-1])  # the newest sample: x = 0
    ghost = blend(DARK["u1"], Color.parse("#1e1e1e").rgb, GHOST_FADE)
    plot = "\n".join("".join(ch for ch, _ in row) for row in rows)
    cols = sorted({n for row in rows for n, (ch, st) in enumerate(row) if braille(ch) and rgb(st) == ghost})
    first, last = read_time(plot, cols[0]), read_time(plot, cols[-1])
    assert abs(first[0] - (120.0 - t_new)) <= 2 * first[1] + 1.0, (first, t_new)
    assert abs(last[0] - (169.0 - t_new)) <= 2 * last[1] + 1.0, (last, t_new)


async def test_a_bad_ghost_log_is_named_and_nothing_breaks(engine: Recording) -> None:
    logs = Path(engine.logs_dir)
    (logs / "bad.log").write_text("% TANK LOG-file\n% Logged variables: u1 u2   TSamp: 1s\n\n0.1  0.2\n0.3\n")
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("b", "enter")
        await pause_until(pilot, lambda: app._notifications, what="the message about bad.log")
        message = list(app._notifications)[-1].message
        assert "bad.log" in message and "line 5" in message, message
        assert app.main.ghost.run is None and app.screen is app.main


def test_the_ghost_follows_each_new_logon(engine: Recording) -> None:
    """LogOn at 40 s, saved, LogOn again at 300 s: the ghost moves to the second."""
    from dataclasses import replace

    from quadtank_tui.engine.snapshot import LogStatus
    from quadtank_tui.ui.ghost import GhostControl

    ghost = GhostControl(None)  # type: ignore[arg-type]  # follow() needs no screen
    snap = engine.snapshot()  # Ts = 0.1 s
    for t, log in ((10.0, LogStatus()), (45.0, LogStatus(active=True, rows=50)),
                   (90.0, LogStatus(active=True, rows=500)), (100.0, LogStatus(rows=600)),
                   (200.0, LogStatus())):
        ghost.follow(replace(snap, t=t, log=log))
        assert ghost.start == (0.0 if t == 10.0 else 40.0), t
    ghost.follow(replace(snap, t=301.0, log=LogStatus(active=True, rows=10)))
    assert ghost.start == pytest.approx(300.0)
    ghost.follow(replace(snap, t=302.0, log=LogStatus(active=True, rows=20)))
    assert ghost.start == pytest.approx(300.0)
