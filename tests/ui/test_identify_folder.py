"""Identify lists the logs of the engine's logs folder, as the Ghost window does:
a terminal attached to a session from another folder listed its own ./logs (empty,
or another run's) instead of the logs the session had just saved."""

from __future__ import annotations

from pathlib import Path

import pytest
from uikit import Recording, make_app
from textual.widgets import SelectionList
from test_trend_view import write_log

from quadtank_tui.ui.screens.identify import IdentifyScreen


async def test_identify_lists_the_engines_logs_from_any_folder(engine: Recording, tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    write_log(Path(engine.logs_dir) / "step.log", 20, 0.3, 0.3)
    elsewhere = tmp_path / "elsewhere"
    (elsewhere / "logs").mkdir(parents=True)
    write_log(elsewhere / "logs" / "other.log", 20, 0.3, 0.3)
    monkeypatch.chdir(elsewhere)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("y")
        await pilot.pause()
        assert isinstance(app.screen, IdentifyScreen)
        listed = app.screen.query_one("#logs", SelectionList)
        names = [str(listed.get_option_at_index(i).prompt) for i in range(listed.option_count)]
        assert names == ["step.log"]
