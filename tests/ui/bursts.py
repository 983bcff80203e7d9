"""Keys as they arrive over SSH, for the pilot tests (issue 17.2)."""

from __future__ import annotations

import time
import unicodedata
from typing import Any

from textual import events
from textual.keys import REPLACED_KEYS, _character_to_key, _get_unicode_name_from_key

#: Longest a burst's keys are waited for, s (a test that passes never waits it out).
BURST_DEADLINE = 60.0


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
    # Until every key was handled, however slow the machine: the deadline is only
    # reached when a key is lost (the assertions after the burst then say which).
    deadline = time.monotonic() + BURST_DEADLINE
    await pilot.pause()
    while getattr(app, "keys_pending", 0) and app.is_running and time.monotonic() < deadline:
        await pilot.pause()
    await pilot.pause()


async def pause_until(pilot: Any, condition: Any, timeout: float = BURST_DEADLINE, what: str = "") -> None:
    """Let the app run until `condition()` holds (a worker's or another thread's
    result reaching the screen); fails after `timeout` s, which a passing test
    never waits out."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what or condition}"
        await pilot.pause(0.02)
