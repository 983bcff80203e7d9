"""The TUI on a session client: the footer line says whose session it is and who
controls it; Exit asks Detach or Stop (an observer only leaves); a refused command
of an observer is shown, and nothing changes in the session."""

from __future__ import annotations

import time

from sessionkit import ThreadSession
from textual.widgets import Static

from quadtank_tui.engine import commands as c
from quadtank_tui.session.client import SessionClient
from quadtank_tui.ui.app import build_app
from quadtank_tui.ui.windows.base import ChoiceWindow, ConfirmWindow

# IDLE: the session samples on a thread of this process, and Textual's pilot waits
# after each key until the process is idle, at most 1 s: at x200 it never is (3 s a
# key, 14 s a test), at x1 (10 samples a second) at once.


async def test_exit_asks_detach_or_stop_and_stop_is_remembered(thread_session) -> None:
    s: ThreadSession = thread_session(speed=1.0)  # see IDLE
    client = SessionClient(s.path)
    app = build_app(client, refresh_interval=0.05)
    async with app.run_test(size=(120, 40)) as pilot:
        bar = app.main.query_one("#session-bar", Static)
        assert "session alice-1 of alice" in str(bar.render()) and "you operate it" in str(bar.render())
        await pilot.press("q")
        await pilot.pause()
        assert isinstance(app.screen, ChoiceWindow)
        assert "Detach:" in app.screen.question and "keeps running" in app.screen.question
        await pilot.press("escape")  # Cancel: nothing chosen
        await pilot.pause()
        assert not client.stop_on_close
        await pilot.press("q")
        await pilot.pause()
        await pilot.click("#choice-1")  # "Stop the session"
        await pilot.pause()
    assert client.stop_on_close
    client.close()  # what the CLI does after the app: stops the session
    s.thread.join(10)
    assert s.reason == "stopped by alice"


async def test_an_observer_sees_who_controls_and_its_keys_change_nothing(thread_session) -> None:
    s: ThreadSession = thread_session(speed=1.0)  # see IDLE
    operator = SessionClient(s.path)
    observer = SessionClient(s.path, role="observer")
    app = build_app(observer, refresh_interval=0.05)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        text = str(app.main.query_one("#session-bar", Static).render())
        assert "alice (pid" in text and "controls session alice-1" in text and "read-only" in text
        await pilot.press("r")  # Run: refused
        deadline = time.monotonic() + 60  # the refusal comes back over the socket
        while not any("read-only" in str(n.message) for n in app._notifications):
            assert time.monotonic() < deadline, "no refusal shown"
            await pilot.pause(0.02)
        assert s.engine.snapshot().state == "Pause"
        await pilot.press("q")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmWindow)
    observer.close()
    assert operator.submit(c.SetState("Run")).result(30).ok
    operator.close()


async def test_an_observer_of_a_stopped_session_is_told_on_the_session_line(thread_session) -> None:
    """The status line's fault is cut at 100 columns ("fault: session alice-1");
    the session line says why the session is gone, whatever the width."""
    s: ThreadSession = thread_session(speed=1.0)  # see IDLE
    observer = SessionClient(s.path, role="observer")
    app = build_app(observer, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        _stop_from_outside(s, observer, "stopped by carol")
        bar = app.main.query_one("#session-bar", Static)
        deadline = time.monotonic() + 60  # a paused screen's tick (0.5 s) shows it
        while not str(bar.render()).startswith("session alice-1 ended"):
            assert time.monotonic() < deadline, str(bar.render())
            await pilot.pause(0.05)
        text = str(bar.render())
        assert text.startswith("session alice-1 ended: stopped by carol; the screen shows its last state")
    observer.close()


async def test_exit_after_the_session_ended_offers_no_stop(thread_session) -> None:
    """Once its session has ended (stopped from outside), the operator's Exit only
    leaves: it never offers to stop "session alice-1", an id that is nobody's now."""
    s: ThreadSession = thread_session(speed=1.0)  # see IDLE
    client = SessionClient(s.path)
    app = build_app(client, refresh_interval=0.05)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        _stop_from_outside(s, client, "stopped by teacher")
        await pilot.press("q")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmWindow)
        assert app.screen.question == "Session alice-1 has ended: stopped by teacher.\nExit?"
        await pilot.press("enter")
        await pilot.pause()
    assert not client.stop_on_close
    client.close()


def _stop_from_outside(s: ThreadSession, client: SessionClient, reason: str) -> None:
    """The session stops for `reason` (as `quadtank stop` by someone else) and `client` sees it go."""
    s.host.request_stop(reason)
    s.thread.join(30)
    assert client.wait_gone(30)


async def test_the_screen_reads_its_session_on_its_own_loop_and_the_thread_comes_back_to_stop_it(
        thread_session) -> None:
    """read_on: no thread of the client's between the session and the screen - the
    updates and a key's answer are read on the app's event loop (the future
    completes on its thread); after the app is gone, closing reads on a thread
    again to hear the session stop."""
    import threading

    s: ThreadSession = thread_session(speed=1.0)  # see IDLE
    client = SessionClient(s.path)
    app = build_app(client, refresh_interval=0.05, read_on=client.read_on)
    ui = threading.get_ident()
    answered: list[int] = []
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        assert not any(t.name == "quadtank-session-client" for t in threading.enumerate())
        fut = client.submit(c.SetState("Run"))
        fut.add_done_callback(lambda f: answered.append(threading.get_ident()))
        end = time.monotonic() + 30
        while not (fut.done() and app.main.snap.state == "Run" and client.snapshot().t > 0.3):
            assert time.monotonic() < end, "the session's answer or updates never came"
            await pilot.pause(0.05)
        assert answered == [ui] and fut.result().ok
        await pilot.press("q")
        await pilot.pause()
        await pilot.click("#choice-1")  # "Stop the session"
        await pilot.pause()
    client.close()  # the app's loop is gone: a thread hears the session stop
    assert client.gone and client.ended == "stopped by alice"
    s.thread.join(10)
    assert s.reason == "stopped by alice"
