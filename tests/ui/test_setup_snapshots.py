"""What the Setup screen and its windows look like (golden SVGs under
__snapshots__; review a changed one with `pytest --snapshot-update` and a look)."""

from __future__ import annotations

from pathlib import Path

import pytest
from textual.widgets import Input

from uikit import open_setup  # noqa: E402


@pytest.fixture
def app(setup_app):
    return setup_app


def test_setup_120x40(app, snap_compare) -> None:
    assert snap_compare(app, terminal_size=(120, 40), run_before=open_setup)


def test_setup_80x24(app, snap_compare) -> None:
    assert snap_compare(app, terminal_size=(80, 24), run_before=open_setup)


def test_wave_window_prbs(app, snap_compare) -> None:
    # Reference 1, wave type switched to PRBS by key: period in samples, seed enabled.
    assert snap_compare(app, terminal_size=(80, 24), run_before=open_setup, press=["i", "ctrl+t", "ctrl+t"])


def test_pid_window_with_extras(app, snap_compare) -> None:
    assert snap_compare(app, terminal_size=(80, 24), run_before=open_setup, press=["4"])


def test_tank_window_with_valve(app, snap_compare) -> None:
    async def type_diameter(pilot) -> None:
        await open_setup(pilot)
        await pilot.press("h", "enter")
        pilot.app.screen.query_one("#f-Diameter", Input).focus()
        await pilot.pause()
        await pilot.press("6", ".", "5")
        await pilot.pause()

    # Tank 1 chosen in the process table; a new diameter, the time constant follows.
    assert snap_compare(app, terminal_size=(80, 24), run_before=type_diameter)


def test_par_window_with_an_error(app, snap_compare) -> None:
    Path("params/broken.par").write_text("% TANK PAR-file\n\nSIMULATION\nValve1 0.5\nValve2 1.7\n")

    async def load_broken(pilot) -> None:
        await open_setup(pilot)
        await pilot.press("f")
        pilot.app.screen.query_one("#name", Input).value = "broken"
        await pilot.pause()
        await pilot.press("ctrl+l")
        await pilot.pause()

    assert snap_compare(app, terminal_size=(80, 24), run_before=load_broken)
