"""The Bookings window (`k` on Main, issue 44): the session's rig's slots, Book
from the From/To fields, Cancel booking on the highlighted one (pilot)."""

from __future__ import annotations

from datetime import datetime, timedelta
from pathlib import Path

import pytest
from textual.widgets import Input, OptionList, Static
from uikit import Recording, make_app

from quadtank_tui.session.bookings import list_bookings
from quadtank_tui.session.lab import load_lab_config
from quadtank_tui.ui.windows.booking_slots import BookingsWindow

ROOT = Path(__file__).resolve().parents[2]


async def test_book_and_cancel_a_slot_from_the_tui(engine: Recording, tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    lab_file = tmp_path / "lab.yaml"
    lab_file.write_text(f"runtime_dir: {tmp_path / 'rt'}\nbookings:\n  slot_minutes: 30\n")
    monkeypatch.setenv("QUADTANK_LAB", str(lab_file))
    engine.info = type("Info", (), {"daq": str(ROOT / "params" / "virtual-rig.yaml")})()  # type: ignore[attr-defined]
    day = (datetime.now() + timedelta(days=1)).strftime("%Y-%m-%d")
    app = make_app(engine)
    async with app.run_test(size=(100, 34)) as pilot:
        await pilot.press("k")
        await pilot.pause()
        window = app.screen
        assert isinstance(window, BookingsWindow)
        assert "127.0.0.1:5020/1" in str(window.query_one("#rules", Static).content)
        window.query_one("#start", Input).value = f"{day} 10:00"
        window.query_one("#end", Input).value = f"{day} 10:45"  # not on a slot
        await window.run_action("book")
        assert "on the lab's slots" in str(window.query_one("#message", Static).content)
        window.query_one("#end", Input).value = f"{day} 11:00"
        await window.run_action("book")
        await pilot.pause()
        assert str(window.query_one("#message", Static).content).startswith("booked: ")
        [made] = list_bookings(load_lab_config())
        assert (made.start.strftime("%Y-%m-%d %H:%M"), made.end.strftime("%H:%M")) == (f"{day} 10:00", "11:00")
        slots = window.query_one("#slots", OptionList)
        assert slots.option_count == 1 and made.user in str(slots.get_option_at_index(0).prompt)
        slots.highlighted = 0
        await window.run_action("cancel_booking")
        await pilot.pause()
        assert str(window.query_one("#message", Static).content).startswith("cancelled: ")
        assert list_bookings(load_lab_config()) == []
        await pilot.press("escape")
        await pilot.pause()
        assert not isinstance(app.screen, BookingsWindow)
