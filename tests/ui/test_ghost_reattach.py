"""A ghost run comes back when a client re-attaches to the same session (issue
28): it belongs to what this user's client shows, remembered on the client's side
by session id and start, not to the session (nor to a new session with a reused id)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from bursts import pause_until
from uikit import Recording, make_app
from test_trend_view import write_log

from quadtank_tui.files.ghost_memory import recall, state_file
from quadtank_tui.session.info import SessionInfo
from quadtank_tui.ui.ghost.window import GhostWindow


class Attached:
    """The engine as a lab session's client shows it: it offers the session
    (engine.handle.LabSession), whose id and start are those of `info`."""

    def __init__(self, engine: Recording, info: SessionInfo) -> None:
        self.engine, self.info = engine, info
        self.session_id, self.started = info.id, info.started
        self.operating, self.gone, self.ended, self.policy = True, False, None, ""

    def lab_session(self) -> Attached:
        return self

    def session_banner(self) -> str:
        return f"session {self.info.id} of {self.info.owner}"

    def stop_on_exit(self) -> None:
        pass

    def __getattr__(self, name: str) -> Any:
        return getattr(self.engine, name)


def info(started: str) -> SessionInfo:
    return SessionInfo(id="qtb-1", owner="student", uid=1000, pid=4242, started=started, plant="quadtank")


async def test_the_ghost_comes_back_on_reattach_and_not_on_a_new_session(
        engine: Recording, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    write_log(Path(engine.logs_dir) / "yesterday.log", 100, 0.5, 0.6)
    first = make_app(Attached(engine, info("2026-11-26T15:00:00")))
    async with first.run_test(size=(120, 40)) as pilot:
        await pilot.press("b")
        assert isinstance(first.screen, GhostWindow)
        await pilot.press("enter")
        await pause_until(pilot, lambda: first.main.ghost.run is not None, what="the ghost")
        start = first.main.ghost.start
    assert recall("qtb-1 2026-11-26T15:00:00") is not None and state_file().is_file()

    other = make_app(Attached(engine, info("2026-11-26T16:00:00")))  # the id reused by a new session
    async with other.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await other.workers.wait_for_complete()
        assert other.main.ghost.run is None

    again = make_app(Attached(engine, info("2026-11-26T15:00:00")))  # the same session, a new client
    async with again.run_test(size=(120, 40)) as pilot:
        await pause_until(pilot, lambda: again.main.ghost.run is not None, what="the ghost back")
        run = again.main.ghost.run
        assert run is not None and run.name == "yesterday.log"
        assert again.main.ghost.start == start
        await pilot.press("B")  # cleared: forgotten too
    assert recall("qtb-1 2026-11-26T15:00:00") is None


def test_an_unreadable_memory_costs_only_the_memory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    state_file().parent.mkdir(parents=True)
    state_file().write_text("{not json")
    assert recall("qtb-1 x") is None


async def test_the_trends_settings_come_back_on_reattach_and_not_on_a_new_session(
        engine: Recording, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 43: zoom (z), autoscale (Z), units (u) and the clock axis (c) as this
    user left them on the session, not the defaults."""
    from quadtank_tui.files.trend_memory import TrendSettings
    from quadtank_tui.files.trend_memory import recall as recall_trends
    from quadtank_tui.ui.widgets.trends import Trend

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    first = make_app(Attached(engine, info("2026-11-26T15:00:00")))
    async with first.run_test(size=(120, 40)) as pilot:
        await pilot.press("z", "Z", "u", "c")
    assert recall_trends("qtb-1 2026-11-26T15:00:00") == TrendSettings(2, False, True, True)
    again = make_app(Attached(engine, info("2026-11-26T15:00:00")))
    async with again.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        view = again.main.query_one("#upper", Trend).view
        assert (view.window, view.autoscale, view.clock is not None) == (600.0, False, True)
        assert view.unit == "V"  # u1 u2 in the pumps' volts
    other = make_app(Attached(engine, info("2026-11-26T16:00:00")))  # the id reused by a new session
    async with other.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        view = other.main.query_one("#upper", Trend).view
        assert (view.window, view.autoscale, view.unit, view.clock) == (300.0, True, "", None)
