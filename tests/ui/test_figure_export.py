"""The E key on Main, Identify and Design: a PNG of what the screen shows, built in
a worker, written next to the logs under a free name that a notification says."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.screens.design import DesignScreen
from quadtank_tui.ui.screens.identify import IdentifyScreen

from uikit import Recording, make_app
from test_identify_screen import simo_logs


def notes(app: Any) -> list[str]:
    return [str(n.message) for n in app._notifications]


async def export(pilot: Any) -> None:
    await pilot.press("E")
    await pilot.app.workers.wait_for_complete()
    await pilot.pause()


async def test_main_exports_the_trends_in_view_twice_without_overwriting(engine: Recording, tmp_path: Path) -> None:
    engine.submit(c.SetState("Run"))
    engine.run_for(60.0)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await export(pilot)
        await export(pilot)
        first, second = tmp_path / "logs" / "trends.png", tmp_path / "logs" / "trends-2.png"
        assert f"Figure saved to {first}" in notes(app) and f"Figure saved to {second}" in notes(app)
        assert first.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert first.read_bytes() == second.read_bytes()  # the same view, the same figure
        assert engine.snapshot().state == "Run"  # nothing sent to the process


async def test_main_before_any_sample_says_there_is_nothing_to_draw(engine: Recording, tmp_path: Path) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await export(pilot)
        assert "No figure: no samples in view yet: Run first" in notes(app)
        assert not list((tmp_path / "logs").glob("*.png"))


@pytest.fixture
def app(setup_app):
    simo_logs(Path("logs"))
    return setup_app


async def test_identify_exports_the_fit_next_to_the_first_log(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("y")
        await pilot.pause()
        await export(pilot)  # before a fit: said, nothing written
        assert "Nothing to draw yet: fit first (f)." in str(pilot.app.screen.query_one("#identify-status").render())
        await pilot.press("space", "f")  # pminus-u1.log alone: G11 and G21 (half the fit and figure)
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        screen = pilot.app.screen
        assert isinstance(screen, IdentifyScreen) and screen.view is not None and len(screen.view.ident.elements) == 2
        await export(pilot)
        assert "Figure saved to logs/pminus-u1.oe.png" in notes(pilot.app)
        assert Path("logs/pminus-u1.oe.png").stat().st_size > 10_000
        assert not list(Path("logs").glob("*-2.png"))


async def test_design_exports_the_chosen_controller(setup_app) -> None:
    async with setup_app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("d")
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        assert isinstance(pilot.app.screen, DesignScreen)
        # the screen opens with the default pair chosen (what `quadtank design` gives)
        assert all(pilot.app.screen.loops[i].chosen is not None for i in (1, 2))
        await pilot.press("enter")  # the highlighted candidate becomes loop 1's
        await pilot.pause()
        assert pilot.app.screen.loops[1].chosen is not None
        await export(pilot)
        assert "Figure saved to logs/design.png" in notes(pilot.app)
        assert Path("logs/design.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
