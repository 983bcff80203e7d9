"""The Bookings window (`k` on Main): the rig's slots, and booking or cancelling one.

The rig is the session's (`quadtank --daq CONFIG`): its bookings are read and
written by this screen's process, which runs as the user (session/bookings.py:
the runtime folder's rules; `quadtank book` and `quadtank bookings` do the same
from a shell).  A session without a rig lists every rig's bookings and books none.
"""

from __future__ import annotations

from datetime import timedelta
from typing import TYPE_CHECKING

from textual import on
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.widgets import Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import Window

if TYPE_CHECKING:
    from quadtank_tui.session.lab import LabConfig


class BookingsWindow(Window[None]):
    """The bookings of the rig `daq` (a DAQ configuration; "" for none)."""

    def __init__(self, daq: str, *, opener: str | None = None) -> None:
        super().__init__("Bookings", opener=opener)
        self.daq = daq
        self.keys: tuple[str, ...] | None = None

    def compose_body(self) -> ComposeResult:
        yield Static("", id="rules", markup=False)
        yield OptionList(id="slots")
        with Horizontal(classes="field"):
            yield Label("From", classes="label")
            yield Input("", id="start", placeholder="HH:MM", compact=True)
        with Horizontal(classes="field"):
            yield Label("To", classes="label")
            yield Input("", id="end", placeholder="HH:MM", compact=True)

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Book", id="book", variant="primary")
        yield KeyButton("Cancel booking", id="cancel_booking")
        yield KeyButton("Close", id="cancel")

    def on_mount(self) -> None:
        self.refresh_list()

    def _lab(self) -> LabConfig:
        from quadtank_tui.session.lab import load_lab_config

        return load_lab_config()

    def refresh_list(self) -> None:
        from quadtank_tui.session.bookings import booking_rules, list_bookings

        rules = self.query_one("#rules", Static)
        slots = self.query_one("#slots", OptionList)
        try:
            lab = self._lab()
            r = booking_rules(lab)
            if self.daq and self.keys is None:
                from quadtank_tui.daq.open import load_rig_config
                from quadtank_tui.session.riglock import rig_keys

                self.keys = rig_keys(load_rig_config(self.daq))
            found = list_bookings(lab, self.keys)
        except (OSError, ValueError) as exc:
            self.show_message(str(exc))
            return
        rig = ", ".join(self.keys) if self.keys else "every rig (this session drives none: it books none)"
        rules.update(f"{rig}\nslots of {r.slot_minutes:g} min, up to {r.horizon_days:g} days ahead, "
                     f"{r.weekly_quota_minutes:g} min a student a week")
        slots.clear_options()
        if not found:
            slots.add_option(Option("no bookings", id="-", disabled=True))
        for b in found:
            slots.add_option(Option(f"{b.start:%a %d %H:%M:%S} - {b.end:%H:%M:%S}  {b.user}  ({b.rig})", id=b.id))

    @on(Input.Submitted)
    async def _submitted(self, event: Input.Submitted) -> None:
        event.stop()
        if event.input.id == "start":
            self.query_one("#end", Input).focus()
        else:
            await self.run_action("book")

    def action_book(self) -> None:
        from quadtank_tui.session.bookings import BookingError, book, parse_when

        if not self.keys:
            self.show_message("this session drives no rig: start one with quadtank --daq CONFIG, "
                              "or book with quadtank book RIG FROM TO")
            return
        try:
            start = parse_when(self.query_one("#start", Input).value)
            text = self.query_one("#end", Input).value
            end = parse_when(text, today=start)
            if end <= start and len(text.strip()) <= 8:
                end += timedelta(days=1)
            made = book(self._lab(), self.keys, start, end)
        except (BookingError, OSError, ValueError) as exc:
            self.show_message(str(exc))
            return
        self.show_message(f"booked: {made.words()}")
        self.refresh_list()

    def action_cancel_booking(self) -> None:
        from quadtank_tui.session.bookings import BookingError, cancel

        slots = self.query_one("#slots", OptionList)
        if slots.highlighted is None:
            self.show_message("choose a booking in the list first")
            return
        option = slots.get_option_at_index(slots.highlighted)
        if not option.id or option.id == "-":
            return
        try:
            gone = cancel(self._lab(), option.id)
        except (BookingError, OSError) as exc:
            self.show_message(str(exc))
            return
        self.show_message(f"cancelled: {gone.words()}")
        self.refresh_list()
