"""The CLI pauses the garbage collector for the TUI's start-up (commands.pause_gc:
about 40 ms of the first frame, benchmarks/tui_cost.py); the app must turn it back
on after its first frame, or a long session would never collect a cycle."""

from __future__ import annotations

import gc

from uikit import Recording

from quadtank_tui.ui.app import build_app
from quadtank_tui.ui.widgets.status_line import StatusLine


async def test_the_collector_paused_for_the_start_runs_again_after_the_first_frame(engine: Recording) -> None:
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0, resume_gc=True)
    gc.disable()
    frozen = gc.get_freeze_count()  # the tests' fixture froze what earlier tests left (conftest.py)
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.pause()
            assert app.screen.query_one(StatusLine).region.height > 0  # the first frame is there
            # Turned on once the screen has refreshed after it (the screen's idle or
            # its update timer runs the callbacks): within a few of its ticks.
            for _ in range(100):
                if gc.isenabled():
                    break
                await pilot.pause(0.01)
            assert gc.isenabled()
            assert gc.get_freeze_count() > frozen  # the start-up's objects, out of later collections
    finally:
        gc.enable()


async def test_an_app_not_told_so_leaves_the_collector_alone(engine: Recording) -> None:
    app = build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
    gc.disable()
    frozen = gc.get_freeze_count()
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.pause()
            assert not gc.isenabled()
            assert gc.get_freeze_count() <= frozen  # nothing frozen (a frozen object may be freed)
    finally:
        gc.enable()
