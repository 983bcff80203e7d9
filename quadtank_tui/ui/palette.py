"""Textual's command palette, with one race closed.

Textual 8.2's palette passes page keys to its option list before the list has laid
out its lines, and OptionList._move_page then fails with KeyError (found by
benchmarks/hardening.py: random keys, the app ended on `KeyError: 0`).  A page key
that comes too early does nothing, as it does on an empty list."""

from __future__ import annotations

from textual.command import CommandPalette


class Palette(CommandPalette):
    """The command palette the app opens (see the module docstring)."""

    def _action_command_list(self, action: str) -> None:
        try:
            super()._action_command_list(action)
        except (KeyError, IndexError):  # the list's lines are not laid out yet
            pass
