"""The Design screen driven by keys: design, choose, apply, and see the new K and
Ti in Main's controller box (what reached the engine is one SetParams)."""

from __future__ import annotations

import pytest
from textual.widgets import DataTable, Input, Static

from quadtank_tui.engine.commands import SetParams
from quadtank_tui.ui.screens.design import DesignScreen
from quadtank_tui.ui.screens.main import MainScreen
from quadtank_tui.ui.widgets.controller_box import ControllerBox

from uikit import make_app, workers_done  # noqa: E402


@pytest.fixture
def app(engine):
    return make_app(engine)


async def _open(pilot) -> DesignScreen:
    await pilot.pause()
    await pilot.press("d")
    await pilot.pause()
    screen = pilot.app.screen
    assert isinstance(screen, DesignScreen)
    await workers_done(pilot.app)
    await pilot.pause()
    return screen


async def _type_model(pilot, screen: DesignScreen, loop: int, text: str) -> None:
    """Clear loop `loop`'s model box, type `text` and Enter, as a user does."""
    box = screen.query_one(f"#model-{loop}", Input)
    box.value = ""
    box.focus()
    await pilot.press(*text, "enter")
    await workers_done(pilot.app)
    await pilot.pause()


async def _apply_through_the_preview(pilot, *, confirm: bool = False) -> None:
    """A, the preview window simulates (a worker), then its Apply (focused when done);
    `confirm`: the simulation warned, so Apply asks once more."""
    from quadtank_tui.ui.windows.base import ChoiceWindow
    from quadtank_tui.ui.windows.design_preview import DesignPreviewWindow

    await pilot.press("A")
    await pilot.pause()
    assert isinstance(pilot.app.screen, DesignPreviewWindow)
    await workers_done(pilot.app)
    await pilot.pause()
    assert pilot.app.screen.result is not None
    await pilot.press("enter")
    await pilot.pause()
    if confirm:
        assert isinstance(pilot.app.screen, ChoiceWindow)
        await pilot.press("right", "enter")  # past "Do not apply" to "Apply anyway"
        await pilot.pause()
    assert isinstance(pilot.app.screen, DesignScreen)


def _box_text(app) -> str:
    return " ".join(str(c.render()) for c in app.screen.query_one(ControllerBox).query(Static))


async def test_design_2x2_apply_shows_in_the_controller_box(app, engine) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await _open(pilot)
        # P- (the preset): the physical g11 fills loop 1, its table has nine rows
        assert screen.query_one("#model-1", Input).value == "2.61/(62.7*s+1)"  # gain, time constant
        assert screen.query_one("#design-table", DataTable).row_count == 9
        await pilot.press("2")
        await workers_done(app)
        await pilot.pause()
        mimo = str(screen.query_one("#design-mimo", Static).render())
        assert "closed loop stable" in mimo
        assert "sampled at h = 0.1 s" in mimo  # the preset's TSamp: the loop as it runs
        assert engine.sent(SetParams) == []  # nothing applied before A
        await _apply_through_the_preview(pilot)
        sent = engine.sent(SetParams)
        assert len(sent) == 1 and sent[0].values["CONTROLLER ONE.K"] == 1.908
        p = engine.snapshot().params
        assert p.get("CONTROLLER ONE.K") == 1.908 and p.get("CONTROLLER ONE.Ti") == 62.7
        assert p.get("CONTROLLER FOUR.K") == 1.758 and p.get("CONTROLLER FOUR.Ti") == 90.34
        await pilot.press("escape")
        await pilot.pause()
        assert isinstance(app.screen, MainScreen)
        text = _box_text(app)
        assert "K 1.908 Ti 62.7" in text and "K 1.758 Ti 90.34" in text


async def test_typed_model_and_chosen_row(app, engine) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await _open(pilot)
        await _type_model(pilot, screen, 1, "1.6592*exp(-2.4*s)/(1.07*s+1)^3")
        table = screen.query_one("#design-table", DataTable)
        assert table.row_count == 9
        # sampled at the preset's 0.1 s (continuous, Andersson: 0.1464, 2.394; this program 0.1468, 2.401)
        assert [str(c) for c in table.get_row_at(4)[:3]] == ["PI Ms 1.4", "0.1483", "2.455"]
        # the new table opens on its suggested row, marked "best"
        best = screen.loops[1].best
        assert best is not None and table.cursor_row == best and str(table.get_row_at(best)[-1]) == "best"
        assert all(str(table.get_row_at(i)[-1]) in ("ok", "best") for i in range(9)
                   if screen.loops[1].rows[i].problem is None)
        table.focus()
        await pilot.press(*["up"] * best, "down", "down", "down", "down", "enter")  # to the top, then row 4
        await pilot.pause()
        assert "loop 1: Kc=0.1483, Ti=2.455  (PI Ms 1.4)" in str(screen.query_one("#design-chosen", Static).render())
        await _apply_through_the_preview(pilot)
        p = engine.snapshot().params
        assert p.get("CONTROLLER ONE.K") == 0.1483 and p.get("CONTROLLER FOUR.K") == 1.758  # loop 2: the default design, as `quadtank design`


async def test_a_bad_model_is_pointed_at(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await _open(pilot)
        await _type_model(pilot, screen, 2, "1/(s+1")
        assert any("column 7" in n.message for n in app._notifications)
