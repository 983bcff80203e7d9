"""Issue 43's smaller items, each as seen on screen: the help line of `t`, the
title of a refused command's notification, the Setup's sampling line, the
footer's session line at 80x24."""

from __future__ import annotations

from concurrent.futures import Future

from textual.binding import Binding

from uikit import Recording, make_app

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.commands import CommandResult
from quadtank_tui.ui.labels import TYPES, command_title
from quadtank_tui.ui.screens.main import MainScreen
from quadtank_tui.ui.screens.setup import SetupScreen


def test_the_help_line_of_t_names_every_controller_family() -> None:
    families = {"PID", "General", "state feedback", "MPC"}
    assert {f for f in families if any(f.lower() in name.lower() for *_, name in TYPES)} == families
    for screen in (MainScreen, SetupScreen):
        (t,) = [b for b in screen.BINDINGS if isinstance(b, Binding) and b.key == "t"]
        assert all(f in t.tooltip for f in families), (screen.__name__, t.tooltip)


def test_a_refused_command_is_titled_in_the_screens_words() -> None:
    assert command_title(c.SetState("Run")) == "Run"
    assert command_title(c.SetOperation("Active")) == "Active"
    assert command_title(c.SetControlMode("Automatic")) == "Automatic"
    assert command_title(c.AddWater(2, 0.1)) == "Add water"
    # every command without a mode word has a title of words, none a class name
    from dataclasses import fields, is_dataclass

    from quadtank_tui.ui import labels

    kinds = [k for k in vars(c).values() if isinstance(k, type) and is_dataclass(k) and k is not CommandResult
             and k.__module__ == c.__name__]
    assert len(kinds) >= 20
    for kind in kinds:
        if {f.name for f in fields(kind)} & {"state", "operation", "mode"}:
            continue
        title = labels._COMMAND_TITLES[kind.__name__]
        assert title in ("LogOn", "LogOff") or " " in title or title.istitle(), (kind.__name__, title)


async def test_a_refusal_on_screen_is_not_titled_with_a_class_name(engine: Recording) -> None:
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        refused: Future[CommandResult] = Future()
        refused.set_result(CommandResult.refused("the rig is not answering"))
        engine.submit = lambda command: refused  # type: ignore[method-assign]  # the engine refuses
        app.main.send(c.SetState("Run"))
        await pilot.pause()
        (note,) = [n for n in app._notifications if "rig is not answering" in n.message]
        assert note.title == "Run"


async def test_setup_says_the_sampling_time_and_its_key_apart(setup_engine: Recording) -> None:
    app = make_app(setup_engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("S")
        await pilot.pause()
        line = str(app.screen.query_one("SamplingLine").render())
        assert "100 ms" in line and "ms s" not in line.replace("  ", " ").replace("  ", " ")
        assert "s to change" in line


def test_the_session_line_keeps_the_role_at_80_columns() -> None:
    from quadtank_tui.ui.widgets.session_bar import fit_banner

    line = "session root-1 of root: root (pid 25996) controls session root-1; you operate it"
    assert fit_banner(line, 118) == line
    assert fit_banner(line, 78) == "session root-1 of root: root (pid 25996) controls it; you operate it"
    assert fit_banner(line, 50) == "root-1 of root: root controls it; you operate it"
    observer = "session alice-1 of alice: bob (pid 12) controls session alice-1; read-only: you observe it"
    assert fit_banner(observer, 78).endswith("read-only: you observe it") and len(fit_banner(observer, 78)) <= 78


async def test_the_session_line_at_80x24_on_main(engine: Recording, monkeypatch: object) -> None:
    from quadtank_tui.ui.widgets.session_bar import SessionBar

    line = "session root-1 of root: root (pid 25996) controls session root-1; you operate it"
    monkeypatch.setattr(MainScreen, "_session_banner", lambda self: line)  # type: ignore[attr-defined]
    app = make_app(engine)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        bar = app.main.query_one("#session-bar", SessionBar)
        shown = "\n".join(strip.text for strip in app.screen._compositor.render_strips())
        assert bar.region.height == 1 and "controls it; you operate it" in shown
