"""Issue 17 (5, 6) and issue 18 (8-10) on the Setup screen and in windows: values
that are refused must be said in full, never analysed as if valid, and typed text
is never markup nor a crash (App.run_test on a manual-clock engine)."""

from __future__ import annotations

import re

from bursts import burst
from uikit import open_setup

from textual.widgets import Input, Static

from quadtank_tui.engine import commands as c
from quadtank_tui.ui.widgets.analysis_panel import AnalysisPanel
from quadtank_tui.ui.windows.logging import LoggingWindow
from quadtank_tui.ui.windows.tank_setup import TankSetupWindow


def shown(widget: Static) -> str:
    """The text a widget shows on the screen, its lines joined (what is cut off
    at its edge is not there)."""
    lines = widget.render_lines(widget.size.region)
    return re.sub(r"\s+", " ", " ".join(strip.text for strip in lines)).strip()


async def _tank_field(pilot, tank: int, field: str) -> TankSetupWindow:
    await open_setup(pilot)
    await pilot.app.screen.run_action(f"tank({tank})")
    await pilot.pause()
    window = pilot.app.screen
    assert isinstance(window, TankSetupWindow)
    window.query_one(f"#f-{field}", Input).focus()
    await pilot.pause()
    await burst(pilot, "ctrl+a", "ctrl+k")
    return window


# --- 17.5: refusals are wrapped inside the window, never cut at its edge ----------------------

async def test_a_long_refusal_is_shown_whole_inside_the_window(setup_app) -> None:
    async with setup_app.run_test(size=(80, 24)) as pilot:
        await open_setup(pilot)
        await pilot.press("s")  # the sampling time window
        await pilot.pause()
        window = setup_app.screen
        await burst(pilot, "ctrl+a", "ctrl+k", "1", "0", "enter")
        await pilot.pause()
        error = window.query_one("#e-0", Static)
        reason = re.sub(r"\s+", " ", str(error.render())).strip()
        assert reason.startswith("must be >= 50") and len(reason) > 20
        assert shown(error) == reason
        dialog = window.query_one("#dialog")
        assert dialog.content_region.contains_region(error.region)


# --- 17.6: no analysis of refused values ----------------------------------------------------

async def test_the_live_analysis_waits_for_valid_values(setup_app) -> None:
    async with setup_app.run_test(size=(120, 40)) as pilot:
        window = await _tank_field(pilot, 1, "Valve")
        await burst(pilot, *"1.5")
        panel = window.query_one("#tank-analysis", AnalysisPanel)
        text = str(panel.render())
        assert "phase" not in text and "Valve Pos. 1.5 is refused (must be <= 1" in text
        await burst(pilot, "ctrl+a", "ctrl+k", *"0.5")  # valid again
        await pilot.pause()
        assert "γ1+γ2 1.10 > 1: minimum phase" in str(panel.render())  # valve 2 at 0.6


# --- 18.10: an absurd diameter is refused, not an OverflowError -------------------------------

async def test_a_huge_diameter_is_refused_with_a_message(setup_app) -> None:
    async with setup_app.run_test(size=(120, 40)) as pilot:
        window = await _tank_field(pilot, 1, "Diameter")
        await burst(pilot, *"1e308")
        await pilot.pause()
        assert "must be <= 100, got 1e+308" in str(window.query_one("#e-Diameter", Static).render())
        await pilot.press("escape")
        await pilot.pause()
    assert setup_app.return_code in (None, 0)


# --- 18.8: typed text is never markup ---------------------------------------------------------

async def test_typed_markup_is_shown_as_typed(setup_app) -> None:
    async with setup_app.run_test(size=(120, 40)) as pilot:
        await burst(pilot, "1", "ctrl+a", "ctrl+k", *"[/x]", "enter")      # K = [/x]
        await pilot.pause()
        error = setup_app.screen.query_one("#e-0", Static)
        assert "[/x]" in shown(error)
        await burst(pilot, "ctrl+a", "ctrl+k", *"[b]1", "enter")
        await pilot.pause()
        assert "[b]1" in shown(error)
        await pilot.press("escape")
        await open_setup(pilot)
        await pilot.press("f")                                             # the .par window
        await pilot.pause()
        await burst(pilot, *"[/x]", "enter")
        await pilot.pause()
        assert "'[/x]'" in shown(setup_app.screen.query_one("#par-error", Static))
    assert setup_app.return_code in (None, 0)


# --- 18.9: a file name too long for the file system -------------------------------------------

async def test_a_very_long_log_name_is_refused_not_a_crash(setup_app) -> None:
    async with setup_app.run_test(size=(120, 40)) as pilot:
        await pilot.press("l")
        window = setup_app.screen
        assert isinstance(window, LoggingWindow)
        window.query_one("#file", Input).value = "a" * 300
        await pilot.pause()
        assert "too long" in shown(window.query_one("#file-error", Static))
        await pilot.press("ctrl+o")                                        # LogOn refused
        await pilot.pause()
        assert setup_app.screen is window
    assert not setup_app.engine.sent(c.LogOn)
    assert setup_app.return_code in (None, 0)
