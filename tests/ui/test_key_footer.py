"""The footer rebuilds its keys only when the keys it shows change (key_footer.py):
not at each Tab between a window's fields, nor when a window opens over its
screen or closes; at once when a key appears."""

from __future__ import annotations

from typing import Any

from textual.widgets._footer import FooterKey

from quadtank_tui.ui.widgets.key_footer import KeyFooter
from quadtank_tui.ui.windows.base import Window

from uikit import make_app  # noqa: E402


def keys(screen: Any) -> list[FooterKey]:
    return list(screen.query_one(KeyFooter).query(FooterKey))


def shown(screen: Any) -> list[tuple[str, str, bool]]:
    return [(k.key, k.action, k.disabled) for k in keys(screen)]


async def test_the_footer_is_rebuilt_only_when_its_keys_change(engine: Any) -> None:
    app = make_app(engine)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        main = app.screen
        main_keys = keys(main)
        assert [k.key for k in main_keys][:3] == ["S", "t", "i"], shown(main)
        await pilot.press("i")  # the Input window: fields, Tab between them
        await pilot.pause()
        window = app.screen
        assert isinstance(window, Window)
        before = keys(window)
        assert ("escape", "cancel", False) in shown(window)
        await pilot.press("tab", "tab")  # the next two fields (the third is a Switch, with a key of its own)
        await pilot.pause()
        assert app.focused is not None and app.focused.id == "f-2"
        assert keys(window) == before  # the same FooterKey objects: not rebuilt
        await pilot.press("tab")
        await pilot.pause()
        assert app.focused is not None and app.focused.id == "f-3"
        assert keys(window) != before and len(shown(window)) == len(before) + 1  # its key, added
        await pilot.press("escape")
        await pilot.pause()
        assert app.screen is main and keys(main) == main_keys
