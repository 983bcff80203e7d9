"""The Main screen and every window, as pictures (pytest-textual-snapshot).

Deterministic: the engine's clock is manual (it moves only when told to), the
PRBS seed and the wall clock are fixed.
Update the golden SVGs with `pytest tests/ui --snapshot-update` after checking the
report's pictures by eye.
"""

from __future__ import annotations

import pytest
from uikit import Recording, make_app
from textual.pilot import Pilot

from quadtank_tui.engine.commands import LogOn, SetParams, SetState
from quadtank_tui.ui.app import QuadTankApp


def test_main_at_startup_120x40(snap_compare, engine: Recording) -> None:
    assert snap_compare(make_app(engine), terminal_size=(120, 40))


def test_main_at_startup_80x24(snap_compare, engine: Recording) -> None:
    assert snap_compare(make_app(engine), terminal_size=(80, 24))


@pytest.mark.parametrize(
    "keys",
    [
        pytest.param(["t"], id="controller_type"),
        pytest.param(["1"], id="pid_element"),
        pytest.param(["t", "3", "_", "4"], id="general_element"),
        pytest.param(["i"], id="input_signal"),
        pytest.param(["h", "down", "0", "full_stop", "1"], id="tank_simul"),
        pytest.param(["v"], id="pump"),
        pytest.param(["G"], id="plot_type"),
    ],
)
def test_window(snap_compare, engine: Recording, keys: list[str]) -> None:
    assert snap_compare(make_app(engine), terminal_size=(80, 24), run_before=_pressed_and_settled(keys))


def _pressed_and_settled(keys: list[str]):
    """The keys, then the window given time to compose and lay out its content: a
    CI run at full load once took the Pump window's picture with its border drawn
    and its body not yet (the snapshot plugin pauses once after the keys)."""
    async def before(pilot: Pilot) -> None:
        await pilot.press(*keys)
        for _ in range(3):
            await pilot.pause()
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
    return before


def _logging_at_45_percent(engine: Recording):
    async def before(pilot: Pilot) -> None:
        for command in (SetParams({"LOGGING.Points": 600, "LOGGING.LogFile": "step1"}),
                        SetState("Run"), LogOn()):
            engine.submit(command)
        engine.run_for(270.0)
        assert isinstance(pilot.app, QuadTankApp)
        pilot.app.main.refresh_view()
        await pilot.pause()
    return before


def test_logging_window_with_progress(snap_compare, engine: Recording) -> None:
    assert snap_compare(make_app(engine), terminal_size=(80, 24), press=["l"],
                        run_before=_logging_at_45_percent(engine))


def test_exit_confirmation_with_unsaved_log(snap_compare, engine: Recording) -> None:
    assert snap_compare(make_app(engine), terminal_size=(80, 24), press=["q"],
                        run_before=_logging_at_45_percent(engine))
