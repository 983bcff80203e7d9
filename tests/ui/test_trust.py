"""Issue 17 "Wrong or lost information" and issue 18's UI crashes, through the app
as a user drives it (App.run_test on a manual-clock engine).

Each test failed on the code before its fix: what is checked is the file on disk,
the value that reached the engine, or the text on the screen.
"""

from __future__ import annotations

from pathlib import Path

from conftest import Recording, make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.files.log import read_log
from quadtank_tui.ui.windows.base import ChoiceWindow


def _logs(engine: Recording) -> Path:
    return Path(engine.loop.logs_dir)


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
        assert app.screen.focused is not None and "Save" in str(app.screen.focused.label)
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
        assert "Save as logs/data-2.log" in str(app.screen.query_one("#choice-0").label)
        await pilot.press("escape")                       # Cancel: nothing happens
        assert app.screen is app.main and engine.snapshot().log.unsaved
        await pilot.press("q", "tab", "enter")            # Discard and exit
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
        await pilot.press("l", "tab", "ctrl+a", "ctrl+k", *"second", "ctrl+o")
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
