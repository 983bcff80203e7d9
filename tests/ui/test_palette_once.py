"""The command palette opens once (issue 18, found by benchmarks/hardening.py's
random keys): ctrl+p, then Help (F1) over it, then ctrl+p again pushed a second
palette and the app ended on `DuplicateIds: '--command-palette'`."""

from __future__ import annotations

from typing import Any

from uikit import make_app
from textual.command import CommandPalette


async def _open_palette(pilot: Any) -> CommandPalette:
    """ctrl+p as a user types it; the palette in front."""
    await pilot.press("ctrl+p")
    await pilot.pause()
    palette = pilot.app.screen
    assert isinstance(palette, CommandPalette)
    return palette


async def test_ctrl_p_under_help_does_not_open_a_second_palette(engine) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        for key in ("ctrl+p", "f1", "ctrl+p"):
            await pilot.press(key)
        await pilot.pause()
        assert app.is_running
        assert sum(isinstance(s, CommandPalette) for s in app.screen_stack) == 1
        for _ in range(3):
            await pilot.press("escape")
        assert app.screen is app.main


async def test_a_page_key_before_the_palette_list_is_laid_out_does_nothing(engine) -> None:
    """Found by benchmarks/hardening.py's random keys: Textual's palette passed
    pageup to its option list before the list had laid out its lines and the app
    ended on `KeyError: 0` (OptionList._move_page).  The state that race leaves
    (options, no lines) is made here directly."""
    from textual.command import CommandList

    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        palette = await _open_palette(pilot)
        command_list = palette.query_one(CommandList)
        command_list.add_option("x")
        await pilot.pause()
        command_list.highlighted = 0
        await pilot.pause()
        command_list._index_to_line.clear()  # as before the first layout
        palette._action_command_list("page_up")
        palette._action_command_list("page_down")
        await pilot.pause()
        assert app.is_running and app.screen is palette


async def test_the_gathering_worker_of_a_palette_without_its_list_does_nothing(engine) -> None:
    """Found by benchmarks/hardening.py's random keys (11,724; `ctrl+p` then keys that
    closed it): Textual's command-gathering worker ran after the palette had lost its
    list and the app ended on `WorkerFailed: NoMatches: CommandList`."""
    from textual.command import CommandList

    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        palette = await _open_palette(pilot)
        await palette.query_one(CommandList).remove()
        worker = palette._gather_commands("x")
        await worker.wait()
        await pilot.pause()
        assert app.is_running and worker.error is None


async def test_a_palette_that_loses_its_list_while_it_gathers_ends_quietly(engine, monkeypatch) -> None:
    """Found by issue 41's key fuzz (benchmarks/key_fuzz.py, seed 3, its last key):
    the app closed while the palette gathered, and Textual's worker, going on,
    queried the list that was gone: `WorkerFailed: NoMatches: CommandList`."""
    from textual.command import CommandList, CommandPalette

    async def gathers_while_it_closes(palette, search_value):
        await palette.query_one(CommandList).remove()  # the list goes under the gathering worker
        palette.query_one(CommandList)  # what Textual's _refresh_command_list then does

    monkeypatch.setattr(CommandPalette._gather_commands, "__wrapped__", gathers_while_it_closes)
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        palette = await _open_palette(pilot)
        worker = palette._gather_commands("x")
        await worker.wait()
        await pilot.pause()
        assert app.is_running and worker.error is None
