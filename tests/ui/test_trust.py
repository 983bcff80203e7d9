"""Issue 17 "Wrong or lost information" and issue 18's UI crashes, through the app
as a user drives it (App.run_test on a manual-clock engine).

Each test failed on the code before its fix: what is checked is the file on disk,
the value that reached the engine, or the text on the screen.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from textual.widgets import Button, Input

from bursts import burst
from uikit import Recording, make_app, plot_text

from quadtank_tui.engine import commands as c
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.ui.widgets.process_image import ALARM, ProcessImage
from quadtank_tui.ui.plot_axes import DOTS, y_axis
from quadtank_tui.ui.widgets.trends import Trend
from quadtank_tui.ui.windows.base import ChoiceWindow
from quadtank_tui.ui.windows.process import TankWindow


def _logs(engine: Recording) -> Path:
    return Path(engine.logs_dir)


def _log_rows(engine: Recording, seconds: float) -> None:
    for command in (c.SetState("Run"), c.LogOn()):
        engine.submit(command)
    engine.run_for(seconds)


# --- 17.3: Exit with an unsaved log saves by default ---------------------------------------

async def test_exit_with_an_unsaved_log_saves_it_by_default(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        _log_rows(engine, 5.0)
        await pilot.press("q")
        assert isinstance(app.screen, ChoiceWindow)
        assert isinstance(app.screen.focused, Button) and "Save" in str(app.screen.focused.label)
        await pilot.press("enter")
        await pilot.pause()
    assert app.return_code == 0
    saved = read_log(_logs(engine) / "data.log")
    assert len(saved.data) == 50  # 5 s at Ts = 0.1 s
    assert not list(_logs(engine).glob("*.partial"))


async def test_exit_never_overwrites_and_cancel_keeps_everything(engine: Recording) -> None:
    (_logs(engine) / "data.log").write_text("% an earlier log\n")
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        _log_rows(engine, 2.0)
        await pilot.press("q")
        assert "saves it as logs/data-2.log (logs/data.log exists and is kept)" in str(
            app.screen.query_one("#question").render())
        await pilot.press("escape")                       # Cancel: nothing happens
        assert app.screen is app.main and engine.snapshot().log.unsaved
        await burst(pilot, "q", "tab", "enter")            # Discard and exit
        await pilot.pause()
    assert engine.sent(c.LogDiscard) == [c.LogDiscard()]
    assert (_logs(engine) / "data.log").read_text() == "% an earlier log\n"
    assert sorted(p.name for p in _logs(engine).iterdir()) == ["data.log"]


async def test_palette_quit_asks_the_exit_questions(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        _log_rows(engine, 1.0)
        await app.run_action("quit")
        await pilot.pause()
        assert isinstance(app.screen, ChoiceWindow), "quit must not bypass the Exit questions"
        await pilot.press("escape")
        assert app.screen is app.main
    assert engine.snapshot().log.unsaved


# --- 17.7: LogOn under a new name while a log is unsaved ------------------------------------

async def test_logon_under_a_new_name_asks_about_the_unsaved_log(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        _log_rows(engine, 3.0)
        engine.submit(c.LogOff())
        await burst(pilot, "l", "tab", "ctrl+a", "ctrl+k", *"second", "ctrl+o")
        await pilot.pause()
        assert isinstance(app.screen, ChoiceWindow)
        assert "30 rows" in str(app.screen.query_one("#question").render())
        await pilot.press("enter")                        # Save as logs/data.log, then LogOn
        await pilot.pause()
        engine.run_for(1.0)
    assert len(read_log(_logs(engine) / "data.log").data) == 30
    assert engine.snapshot().log.active and engine.snapshot().params.logging.log_file == "second"
    assert sorted(p.name for p in _logs(engine).iterdir()) == ["data.log", "second.log.partial"]


def test_engine_never_leaves_an_unsaved_log_as_a_silent_partial(engine: Recording) -> None:
    _log_rows(engine, 2.0)
    engine.submit(c.SetParams({"LOGGING.LogFile": "other"}))
    result = engine.submit(c.LogOn()).result()
    assert result.ok and any("20 rows" in w and "data-recovered.log" in w for w in result.warnings)
    assert len(read_log(_logs(engine) / "data-recovered.log").data) == 20
    assert not (_logs(engine) / "data.log.partial").exists()


# --- 17.2: a burst of keys goes where the person typing meant ---------------------------------

async def test_keys_typed_right_after_tab_land_in_the_next_field(engine: Recording) -> None:
    engine.engine.submit(c.SetParams({"CONTROLLER ONE.K": 1.0, "CONTROLLER ONE.Ti": 10.0}))
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "1", "ctrl+a", "ctrl+k", *"3.0", "tab", "3", "0", "enter")
        await pilot.pause()
        assert app.screen is app.main, "Enter (Set) closed the window"
    assert engine.sent(c.SetParams) == [c.SetParams({"CONTROLLER ONE.K": 3.0, "CONTROLLER ONE.Ti": 30.0})]
    p = engine.snapshot().params
    assert (p.get("CONTROLLER ONE.K"), p.get("CONTROLLER ONE.Ti")) == (3.0, 30.0)


async def test_a_burst_into_the_logging_window(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "l", "ctrl+a", "ctrl+k", "6", "0", "0", "tab", "ctrl+a", "ctrl+k",
                    *"session1", "enter", "r")
        await pilot.pause()
        assert app.screen is app.main
    assert engine.sent(c.SetParams) == [c.SetParams({"LOGGING.Points": 600, "LOGGING.LogFile": "session1"})]
    assert engine.sent(c.SetState) == [c.SetState("Run")], "the key after Enter reached Main"


# --- 17.4: the Tanks window: choosing a tank never types; the amount must fit ----------------

async def test_choosing_a_tank_does_not_type_and_the_amount_must_fit(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("h")
        assert isinstance(app.screen, TankWindow)
        window = app.screen
        level = engine.snapshot().y[1]
        await burst(pilot, "2", *"0.9", "enter")      # more than tank 2 has room for
        assert app.screen is window and window.selected == 2
        assert window.query_one("#amount", Input).value == "0.9"
        error = str(window.query_one("#amount-error").render())
        assert f"tank 2 has room for {1 - level:.2f}" in error
        await burst(pilot, "ctrl+a", "ctrl+k", *"-0.9", "enter")   # more than is there
        assert f"tank 2 holds only {level:.2f}" in str(window.query_one("#amount-error").render())
        await burst(pilot, "ctrl+a", "ctrl+k", *"0.1", "enter")
        await pilot.pause()
        assert app.screen is app.main
    assert engine.sent(c.AddWater) == [c.AddWater(2, 0.1)]


# --- 17.1: the trend's y labels name the rows they are on -----------------------------------

_LABEL = re.compile(r"^\s*(-?\d+(?:\.\d+)?)\s*┤")


def read_constant(plot: str) -> tuple[float, float]:
    """The value of the one horizontal line in `plot` (plotext text), read off
    the y labels as a person would (the label on its row, or between the labelled
    rows), and half a row in those units."""
    lines = plot.splitlines()
    labelled = [(row, float(m.group(1))) for row, line in enumerate(lines) if (m := _LABEL.match(line))]
    drawn = {row for row, line in enumerate(lines)
             if any(0x2801 <= ord(ch) <= 0x28FF for ch in line.partition("┤")[2])}
    assert len(labelled) >= 2 and len(drawn) == 1, plot
    (r0, v0), (r1, v1) = labelled[0], labelled[-1]
    per_row = (v1 - v0) / (r1 - r0)
    row = drawn.pop()
    return v0 + (row - r0) * per_row, abs(per_row) / 2


async def test_trend_labels_read_back_a_constant_at_every_size(engine: Recording) -> None:
    engine.submit(c.SetState("Run"))
    engine.run_for(20.0)  # Manual: u1 = u2 = 0.300 all along
    assert engine.snapshot().u == (0.3, 0.3)
    for size in ((80, 24), (120, 40), (100, 30)):
        app = make_app(engine)
        async with app.run_test(size=size) as pilot:
            app.main.refresh_view()
            await pilot.pause()
            plot = plot_text(app.main.query_one("#upper", Trend))
        value, half_row = read_constant(plot)
        assert abs(value - 0.300) <= half_row, (size, value, plot)
        labels = [float(m.group(1)) for line in plot.splitlines() if (m := _LABEL.match(line))]
        assert len(set(labels)) == len(labels), "two labels on one row"
        assert all(abs(v * 1000 - round(v * 1000)) < 1e-9 for v in labels), labels  # round numbers


def test_y_axis_rows_are_round_values_centred_under_their_dots() -> None:
    for lo, hi, rows in ((0.28, 0.32, 6), (0.0, 1.0, 30), (0.352, 0.372, 33), (-0.05, 1.02, 8)):
        axis = y_axis(lo, hi, rows)
        step = (axis.hi - axis.lo) * DOTS / (DOTS * rows - 1)  # value per row
        for tick in axis.ticks:
            dot = math.floor(0.5 + (DOTS * rows - 1) * (tick - axis.lo) / (axis.hi - axis.lo))
            assert dot % DOTS in (1, 2), (lo, hi, rows, tick)  # the middle dots of its row
            assert abs(tick / step - round(tick / step)) < 1e-6
        assert axis.lo <= lo and hi <= axis.hi


# --- 17.8: a spilling tank raises an alarm ------------------------------------------------------

async def test_a_tank_that_overflows_in_simul_raises_an_alarm(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        for command in (c.SetParams({"REFERENCE ONE.Mean": 1.0, "REFERENCE TWO.Mean": 1.0}),
                        c.SetState("Run")):
            engine.submit(command)
        engine.run_for(2.0)
        app.main.refresh_view()
        await pilot.pause()
        image = app.main.query_one(ProcessImage)
        assert image.spilling == frozenset() and not app._notifications
        engine.run_for(298.0)  # pumps at 10 V: tanks 1 and 2 fill to the brim
        app.main.refresh_view()
        await pilot.pause()
        assert engine.snapshot().y[:2] == (1.0, 1.0)
        assert image.spilling == frozenset({1, 2})
        assert [n.message for n in app._notifications] == [
            "Tanks 1 and 2 overflow: water spills out of the process."]
        drawn = image.render()
        marked = "".join(drawn.plain[span.start:span.end] for span in drawn.spans if span.style == ALARM)
        assert marked == "1:1.002:1.00"  # the two tanks' labels, white on red
        engine.submit(c.SetState("Pause"))
        app.main.refresh_view()
        assert image.spilling == frozenset()


def test_a_full_narrow_tank_does_not_read_as_empty() -> None:
    """At 80x24 a tank's label keeps three characters: 1.00 was cut to ".00"."""
    from quadtank_tui.ui.widgets.process_image import Canvas, draw_tank

    for level, shown in ((1.0, "1.0"), (0.62, ".62"), (0.0, ".00")):
        canvas = Canvas(5, 3)
        draw_tank(canvas, 0, 0, 5, 2, level, 1, spilling=level == 1.0)
        assert canvas.render().plain.splitlines()[2] == f"└{shown}┘"
