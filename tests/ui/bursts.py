"""Keys as they arrive over SSH, for the pilot tests (issue 17.2)."""

from __future__ import annotations

import unicodedata
from typing import Any

from textual import events
from textual.keys import REPLACED_KEYS, _character_to_key, _get_unicode_name_from_key


async def burst(pilot: Any, *keys: str) -> None:
    """Keys as they arrive over SSH: all in the driver's queue before the app has
    handled the first (Pilot.press waits for the app between keys)."""
    app = pilot.app
    for key in keys:  # made as Pilot.press makes them
        if len(key) == 1 and not key.isalnum():
            key = _character_to_key(key)
        try:
            char: str | None = unicodedata.lookup(_get_unicode_name_from_key(REPLACED_KEYS.get(key, key)))
        except KeyError:
            char = key if len(key) == 1 else None
        app._driver.send_message(events.Key(key, char))
    for _ in range(200):  # until every key was handled (a loaded machine is slow)
        await pilot.pause()
        if not getattr(app, "keys_pending", 0):
            break
    await pilot.pause()
