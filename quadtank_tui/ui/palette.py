"""Textual's command palette, with two races closed (both found by
benchmarks/hardening.py's random keys, each ending the app).

- Textual 8.2's palette passes page keys to its option list before the list has
  laid out its lines, and OptionList._move_page fails with `KeyError: 0`: a page key
  that comes too early does nothing, as it does on an empty list.
- Its command-gathering worker can start after the palette lost its children (the
  palette closed by the next keys) and fails with `NoMatches: CommandList`: a
  palette that is no longer there gathers nothing.  It can also lose them while it
  gathers (the app closing under it: issue 41's key fuzz, seed 3, at its last key):
  the `NoMatches` of a palette whose list is gone by then ends the worker quietly."""

from __future__ import annotations

from textual import work
from textual.command import CommandList, CommandPalette
from textual.css.query import NoMatches


class Palette(CommandPalette):
    """The command palette the app opens (see the module docstring)."""

    def _action_command_list(self, action: str) -> None:
        try:
            super()._action_command_list(action)
        except (KeyError, IndexError):  # the list's lines are not laid out yet
            pass

    @work(exclusive=True, group=CommandPalette._GATHER_COMMANDS_GROUP)
    async def _gather_commands(self, search_value: str) -> None:
        if not self.is_attached or not self.query(CommandList):
            return
        try:
            # Textual's @work returns a typed worker factory without the wrapped coroutine's attribute
            await CommandPalette._gather_commands.__wrapped__(self, search_value)  # type: ignore[attr-defined]
        except NoMatches:
            if self.is_attached and self.query(CommandList):
                raise  # not the race: the list is there

