"""Help (? / F1), the command palette, the speed the machine holds, the smallest
terminal and the 80x24 layout (issue 17, "What a modern terminal tool is
expected to have")."""

from __future__ import annotations

import dataclasses
import io
import re

from uikit import Recording, make_app
from rich.console import Console
from textual.binding import Binding

from quadtank_tui.engine.snapshot import LoopStats
from quadtank_tui.ui.screens.help import HelpScreen
from quadtank_tui.ui.screens.main import MainScreen
from quadtank_tui.ui.screens.setup import SetupScreen
from quadtank_tui.ui.screens.too_small import TooSmallScreen
from quadtank_tui.ui.widgets import analysis_panel
from quadtank_tui.ui.widgets.process_image import ProcessImage, draw
from quadtank_tui.ui.widgets.status_line import StatusLine
from quadtank_tui.ui.windows.controller_windows import PIDWindow
from quadtank_tui.ui.windows.logging import LoggingWindow


def screen_text(app) -> str:
    return "\n".join(strip.text for strip in app.screen._compositor.render_strips())


def help_text(app) -> str:
    """Everything the help page says, scrolled or not."""
    console = Console(width=100, record=True, file=io.StringIO())
    for static in app.screen.query("Static"):
        console.print(static.content)
    return console.export_text()


def described(bindings: list[Binding | tuple[str, str] | tuple[str, str, str]]) -> list[Binding]:
    """The bindings that have a description (the screens declare Binding objects only)."""
    assert all(isinstance(b, Binding) for b in bindings), bindings
    return [b for b in bindings if isinstance(b, Binding) and b.description]


async def test_help_lists_every_key_of_main_setup_and_the_windows_and_esc_closes(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("question_mark")
        await pilot.pause()
        assert isinstance(app.screen, HelpScreen)
        text = help_text(app)
        for b in described(MainScreen.BINDINGS) + described(SetupScreen.BINDINGS):
            assert b.tooltip and b.tooltip in text, b
        for b in described(LoggingWindow.BINDINGS):  # its own; Enter, Esc, ctrl+r once for all
            assert b.key in ("ctrl+r", "escape", "enter") or b.description in text
        for words in ("Every window", "Controller type", "1-4", "Plot type", "1-7", "Logging", "ctrl+o",
                      "Parameter files", "ctrl+l", "Exit question"):
            assert words in text, words
        await pilot.press("escape")
        await pilot.pause()
        assert app.screen is app.main
        await pilot.press("f1")
        await pilot.pause()
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("f1")
        await pilot.pause()
        assert app.screen is app.main


async def test_f1_opens_help_over_a_window_and_esc_goes_back_to_it(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("1")
        window = app.screen
        assert isinstance(window, PIDWindow)
        await pilot.press("f1")
        await pilot.pause()
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("escape")
        await pilot.pause()
        assert app.screen is window


async def test_palette_lists_each_action_once_with_key_and_description(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)):
        commands = list(app.get_system_commands(app.main))
    titles = [cmd.title for cmd in commands]
    assert len(titles) == len(set(titles)), sorted(t for t in titles if titles.count(t) > 1)
    assert "Keys" not in titles and "Quit" not in titles and "Help" in titles
    helps = {cmd.title: cmd.help for cmd in commands}
    assert helps["Run"] == "r · Run: sample, control and log"
    assert helps["Mean 1 +"].startswith("] · ")
    assert helps["Time window"] == "z · Trend time window: 2, 5, 10, 30 min"
    assert "--daq" in helps["Active"]


def with_stats(snap, speed: float, samples: int, skipped: int):
    return dataclasses.replace(snap, speed=speed, realtime=False,
                               stats=LoopStats(samples=samples, overruns=min(1, skipped), skipped=skipped))


async def test_status_line_says_the_speed_asked_and_the_speed_held(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)):
        status = app.main.query_one(StatusLine)
        start = engine.snapshot()
        # 40 slots at x16, one of them skipped: 16 * 39 / 40 = 15.6 held.
        for n in range(41):
            status.snapshot = with_stats(start, 16.0, n - (n >= 30), int(n >= 30))
        assert status.snapshot is not None
        assert "speed x16 asked, x15.6 held" in status.numbers(status.snapshot)
        assert "overruns" not in status.numbers(status.snapshot)
        # Every slot kept at x2: just the speed.
        for n in range(41):
            status.snapshot = with_stats(start, 2.0, 100 + n, 1)
        assert status.snapshot is not None and re.search(r"speed x2(?! asked)", status.numbers(status.snapshot))


async def test_below_80x24_the_terminal_is_said_to_be_too_small(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(70, 20)) as pilot:
        await pilot.pause()
        assert isinstance(app.screen, TooSmallScreen)
        assert "terminal too small (70x20, need 80x24)" in screen_text(app)
        await pilot.resize_terminal(80, 24)
        await pilot.pause()
        await pilot.pause()
        assert app.screen is app.main


async def test_at_80x24_tanks_keep_numbers_valves_show_and_footer_fits(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        image = app.main.query_one(ProcessImage)
        drawn = str(image.render())
        for n in (1, 2, 3, 4):
            assert re.search(rf"{n}:\.\d\d", drawn), (n, drawn)
        assert image.border_subtitle == "γ1 0.70 γ2 0.60"
        lines = screen_text(app).splitlines()
        assert any("╰─" in line and "γ1 0.70 γ2 0.60 ─╯" in line for line in lines)
        footer = lines[-1]
        assert "? Help" in footer and "^p palette" in footer and "…" not in footer


def test_the_image_shows_which_pump_feeds_which_tank(engine: Recording) -> None:
    text, boxes = draw(engine.snapshot(), 46, 14)
    rows = text.plain.splitlines()
    box = {b.action: b for b in boxes}
    t1, t2, t3, t4 = (box[f"tank({n})"] for n in (1, 2, 3, 4))
    # Pump 1 (left riser, arrow up) along the top into tank 4, and into tank 1.
    assert rows[0][t4.x0:t4.x0 + 2] == "►┐" and rows[1][t4.x0 + 1] == "┼"
    drain = t1.y0 - 1
    assert rows[drain][t1.x0:t1.x0 + 2] == "►┐"
    # Pump 2 (right riser) along the second row into tank 3, and into tank 2.
    assert rows[1][t3.x1 - 1:t3.x1 + 1] == "┌◄"
    assert rows[drain][t2.x1 - 1:t2.x1 + 1] == "┌◄"
    # The risers go up, the upper tanks drain down into the lower ones.
    assert rows[t1.y1][1] == "▲" and rows[t1.y1][44] == "▲"
    assert rows[drain].count("▼") == 2
    gammas = next(r for r in rows if "γ1" in r)
    assert "γ1 0.70→1 0.30→4" in gammas and "γ2 0.60→2 0.40→3" in gammas


async def test_setup_labels_its_pump_values(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("S")
        await pilot.pause()
        image = app.screen.query_one("#setup-image", ProcessImage)
        assert image.border_subtitle == "P1 P2: the inputs that hold it"
        assert "P1 0.305" in str(image.render())


async def test_setup_analysis_waits_in_a_worker_until_python_control_is_loaded(
        engine: Recording, monkeypatch) -> None:
    import threading

    monkeypatch.setattr(analysis_panel, "_READY", threading.Event())
    analysis_panel.analysis_of.cache_clear()
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("S")
        await pilot.pause()
        panel = app.screen.query_one("#analysis")
        shown = [str(panel.render())]
        await app.workers.wait_for_complete()
        await pilot.pause()
        shown.append(str(panel.render()))
    assert shown[0].startswith("Analysing") or "Zeros" in shown[0]  # the worker may be quick
    assert "Zeros   -0.0580  -0.0172" in shown[1]
    assert analysis_panel.analysis_ready()


async def test_main_warm_up_analyses_the_setting_so_setup_opens_without_importing(
        engine: Recording, monkeypatch) -> None:
    """The warm-up after Main's first frame runs the analysis Setup will show (it
    imports scipy.linalg when it runs): Setup's first open finds it cached.  It
    used to import the module only, and the first open paid the scipy import
    (1.1 s on a loaded machine) in the UI thread."""
    import threading

    monkeypatch.setattr(analysis_panel, "_READY", threading.Event())
    analysis_panel.analysis_of.cache_clear()
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await app.workers.wait_for_complete()
        assert analysis_panel.analysis_ready()
        assert analysis_panel.analysis_of.cache_info().currsize == 1
        await pilot.press("S")
        await pilot.pause()
        assert "Zeros   -0.0580  -0.0172" in str(app.screen.query_one("#analysis").render())
    info = analysis_panel.analysis_of.cache_info()
    assert (info.currsize, info.hits) == (1, 1)
