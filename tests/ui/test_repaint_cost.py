"""What the Main screen writes to the terminal when little or nothing changes.

Over SSH every repaint costs the link (issue 17: 156 KB/s while paused): a paused
screen must write nothing, and a sample repaints only what it changed.  The
headless driver writes nothing, so the app's display step is wrapped and the
updates it would write are rendered to bytes, as the terminal driver would.
"""

from __future__ import annotations

import re
from typing import Any

import pytest
from uikit import Recording, Wire

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.app import QuadTankApp, build_app
from quadtank_tui.ui.screens.setup import SetupScreen
from quadtank_tui.ui.windows.process import TankWindow

#: The screen's refresh interval, s; the engine's default.par samples every 0.1 s.
TICK = 0.05


def paused_app(engine: Recording) -> QuadTankApp:
    """The app with the engine's own (manual) clock as its wall clock, so the age of
    the last sample grows as the paused loop ticks, as it does in a terminal."""
    return build_app(engine, refresh_interval=TICK, wall_clock=engine.clock.now)


async def ticks(app: QuadTankApp, pilot: Any, engine: Recording, seconds: float) -> None:
    """`seconds` of the screen's ticks, the loop ticking at its sampling time."""
    for n in range(round(seconds / TICK)):
        if n % 2:
            engine.step()
        app.main._tick()
        await pilot.pause()


async def check_paused_screen_is_silent(engine: Recording, size: tuple[int, int]) -> None:
    app = paused_app(engine)
    async with app.run_test(size=size) as pilot:
        await ticks(app, pilot, engine, 0.5)  # the first frame and the layout settle
        wire = Wire(app)
        await ticks(app, pilot, engine, 1.0)
    assert engine.snapshot().stats.samples >= 15, "the paused loop ticked"
    assert wire.bytes == 0, f"{wire.bytes} bytes in {len(wire.updates)} updates: {wire.updates[:1]!r}"


async def test_a_paused_screen_writes_nothing_for_a_second(engine: Recording) -> None:
    await check_paused_screen_is_silent(engine, (120, 40))


async def test_a_paused_screen_writes_nothing_at_80x24(engine: Recording) -> None:
    await check_paused_screen_is_silent(engine, (80, 24))


async def test_a_running_sample_repaints_the_numbers_line_and_not_the_rest_of_the_top(engine: Recording) -> None:
    """Run at Ts = 1 s at the operating point, waves off: each sample changes the
    process time and little else the top rows print (levels to 2 decimals, inputs
    to 3); the trends (rows 19-39 at 120x40) redraw when their curves moved."""
    engine.submit(c.SetParams({"SAMPLING TIME.TSamp": 1000}))
    engine.submit(c.SetState("Run"))
    engine.run_for(100.0)
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await ticks(app, pilot, engine, 0.5)  # the first frame and the layout settle (whole-screen repaints)
        wire = Wire(app)
        for _ in range(10):
            engine.step()
            app.main._tick()
            await pilot.pause()
    rows = {int(r) for u in wire.updates for r in re.findall(r"\x1b\[(\d+);\d+H", u)}
    assert 2 in rows, "the process time is shown"
    assert not rows & set(range(1, 2)) and not rows & set(range(3, 19)), sorted(rows)


async def test_the_setup_screen_paused_writes_nothing(engine: Recording) -> None:
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("S")
        await pilot.pause()
        setup = app.screen
        assert isinstance(setup, SetupScreen)
        wire = Wire(app)
        for _ in range(8):  # two seconds of Setup's quarter-second refresh
            engine.step()
            engine.step()
            setup.refresh_view()
            await pilot.pause()
    assert engine.snapshot().stats.samples >= 16
    assert wire.bytes == 0, wire.updates[:1]


async def under_window(engine: Recording, key: str, settle: float) -> Wire:
    """What a second of ticks writes with the window of `key` open, after `settle` s."""
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press(key)
        await ticks(app, pilot, engine, settle)
        wire = Wire(app)
        await ticks(app, pilot, engine, 1.0)
        assert app.screen is not app.main
    return wire


@pytest.mark.parametrize("key", ["v", "h", "l"])  # Pump, Tank, Logging: the live windows
async def test_a_paused_screen_under_a_live_window_writes_nothing(engine: Recording, key: str) -> None:
    """A live window's update repaints the whole screen behind it (about a
    megabyte a second before, from the paused loop's idle ticks alone)."""
    wire = await under_window(engine, key, 0.25)
    assert wire.bytes == 0, f"{wire.bytes} bytes in {len(wire.updates)} updates"


async def test_the_screen_ticks_slower_while_paused(engine: Recording) -> None:
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        app.main._tick()
        assert app.main._interval == 0.25
        engine.submit(c.SetState("Run"))
        app.main._tick()
        assert app.main._interval == TICK
        await pilot.pause()


@pytest.mark.parametrize("key", ["v", "h", "l"])  # Pump, Tank, Logging: the live windows
async def test_a_running_screen_under_a_live_window_repaints_what_changed(engine: Recording, key: str) -> None:
    """Running at Ts = 0.1 s with the wave on (the inputs, the levels and the
    logging progress change every sample): each sample rewrites the few cells that
    changed, not the screen: 31-33 KB a sample before (a reactive set on the
    window repainted all of it, and Textual piled up the regions of the screen
    behind: screens/behind.py), about 2 KB now (1.5 KB without the window)."""
    engine.submit(c.SetParams({"REFERENCE ONE.On": True, "REFERENCE ONE.Period": 2.0,
                               "REFERENCE ONE.Amplitude": 0.2}))
    engine.submit(c.LogOn())
    engine.submit(c.SetState("Run"))
    engine.run_for(10.0)
    wire = await under_window(engine, key, 0.5)
    per_sample = wire.bytes / 10
    assert per_sample < 3000, f"{per_sample:.0f} bytes a sample in {len(wire.updates)} updates"


async def test_under_a_live_window_the_window_follows_each_sample_and_main_once_a_second(
        engine: Recording) -> None:
    """Main, dimmed behind the window, is redrawn at most once a second (each
    redraw renders all of it again for the window's screen: 15 % of a core at Ts
    0.1 s); the Tank window's heights follow every sample."""
    engine.submit(c.SetState("Run"))
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("h")
        window, status = app.screen, app.main._status
        assert isinstance(window, TankWindow)
        seen_window, seen_main = set(), set()
        for _ in range(8):
            engine.step()
            app.main._tick()
            await pilot.pause()
            assert window.snapshot is not None and status.snapshot is not None
            seen_window.add(window.snapshot.t)
            seen_main.add(status.snapshot.t)
    assert len(seen_window) == 8
    assert len(seen_main) <= 2, sorted(seen_main)


async def test_setup_behind_a_window_is_redrawn_at_most_once_a_second(engine: Recording) -> None:
    engine.submit(c.SetState("Run"))
    app = paused_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("S")
        await pilot.press("i")
        setup = app.screen_stack[-2]
        assert isinstance(setup, SetupScreen)
        drawn = set()
        for _ in range(8):
            engine.step()
            setup._tick()
            await pilot.pause()
            drawn.add(setup.snap.t)
        assert type(app.screen).__name__ == "WaveWindow"
    assert len(drawn) <= 2, sorted(drawn)
