"""Keys handled one after the other, as a person typed them.

Textual forwards a key to the widget that has the focus *when the app reads it*,
and the key's non-priority bindings (Tab moving the focus, a digit opening a
window, Enter closing one) run only once the key has bubbled back up to the app.
Over SSH keys arrive in bursts: `3.0`, Tab, `30` all sit in the app's queue before
the Tab has moved the focus, so `30` went into the K field (`K 3.030`).

`OrderedKeys` holds a key back while the previous one is still on its way: until
that key was consumed by a widget or its bindings ran, and, if it opened or
closed a window, until the screen now in front has handled what was posted to it
(a callback through its first-in first-out queue).  Typed characters pass at
once; a key that goes through bindings takes a few to a few hundred
milliseconds on a loaded machine.  A cap keeps a key that is dropped on the way
(its screen closed under it) from holding the others forever.
"""

from __future__ import annotations

from typing import Any

import asyncio
import time
from collections import deque

from textual import events
from textual.app import App
from textual.dom import DOMNode
from textual.message import Message
from textual.screen import Screen

#: Longest a key is waited for before the next one goes anyway, s: only a key
#: dropped on its way (its screen closed under it) waits this long; a window that
#: mounts slowly on a loaded machine (0.5 s was seen at load 6) must not see the
#: keys typed into it go to the screen behind.
KEY_CAP = 2.0
#: How often a key in flight is looked at, s.
POLL = 0.0005


class OrderedKeys(App[None]):
    """An App whose keys reach the focus in the order, and at the place, typed."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._key_backlog: deque[events.Key] = deque()
        self._key_in_flight: events.Key | None = None
        self._key_released: events.Key | None = None
        self._key_done = False
        self._key_bubbled = False
        self._key_waiters: set[asyncio.Task[None]] = set()  # kept: asyncio holds tasks weakly

    @property
    def keys_pending(self) -> int:
        """Keys read but not yet handled (tests wait for 0)."""
        busy = self._key_in_flight is not None or self._key_released is not None
        return len(self._key_backlog) + busy

    async def on_event(self, event: events.Event) -> None:
        if not isinstance(event, events.Key) or event.is_forwarded:
            await super().on_event(event)
            return
        busy = self._key_in_flight is not None or self._key_released is not None or self._key_backlog
        if event is not self._key_released and busy:
            self._key_backlog.append(event)  # the key before it is still on its way
            return
        if not self.screen_stack:  # the app is closing, its screens gone: a key typed behind its quit goes nowhere
            self._key_backlog.clear()
            return
        self._key_released = None
        self._key_in_flight, self._key_done, self._key_bubbled = event, False, False
        screen = self.screen
        await super().on_event(event)
        if not event.is_forwarded:  # a priority binding took it, here and now
            self._key_done = True
        waiter = asyncio.get_running_loop().create_task(self._release_after(event, screen))
        self._key_waiters.add(waiter)
        waiter.add_done_callback(self._key_waiters.discard)

    def post_message(self, message: Message) -> bool:
        if message is self._key_in_flight and message.is_forwarded:
            # Back from the screen (which marks it stopped as it hands it up): not
            # consumed; its bindings run here next.
            self._key_bubbled = True
        return super().post_message(message)

    def _consumed(self, event: events.Key) -> bool:
        """Whether `event` has been dealt with: a widget stopped it, or it came
        back up and the bindings ran."""
        return self._key_done or (event._stop_propagation and not self._key_bubbled)

    async def _on_key(self, event: events.Key) -> None:
        # Textual calls the `_on_key` of every class in the MRO: run App's here,
        # then stop the walk, so its bindings run once and are known to have run.
        await App._on_key(self, event)
        event.prevent_default()
        if event is self._key_in_flight:
            self._key_done = True

    async def _release_after(self, event: events.Key, screen: Screen[object]) -> None:
        """Wait for `event` to be handled, then let the next key go."""
        deadline = time.monotonic() + KEY_CAP
        try:
            await self._settle(event, screen, deadline)
        finally:
            if self._key_in_flight is event:
                self._key_in_flight = None
                if self._key_backlog:
                    self._key_released = self._key_backlog.popleft()
                    self.post_message(self._key_released)

    async def _settle(self, event: events.Key, before: Screen[object], deadline: float) -> None:
        """Until `event` was consumed or its bindings ran; then, if it opened or
        closed a window (or was an Enter, which submits and closes one), until the
        screen now in front has handled what that set going (a window's mount
        focusing its first field).  A key that only typed or moved the focus
        needs no more: the next one goes to the focus of now, behind it in the
        same first-in first-out queue."""
        while not self._consumed(event):
            if time.monotonic() > deadline:
                return
            await asyncio.sleep(POLL)
        try:
            same = self.screen is before and before.is_mounted
        except Exception:  # no screen: the app is closing
            return
        if same and event.key != "enter":
            return
        while time.monotonic() < deadline:
            try:
                screen = self.screen
            except Exception:  # no screen: the app is closing
                return
            if screen.is_mounted and not self._focus_chain_busy(screen):
                await self._drained(screen, deadline)
                if self.screen is screen and not self._focus_chain_busy(screen):
                    return
            else:
                await asyncio.sleep(POLL)

    def _focus_chain_busy(self, screen: Screen[object]) -> bool:
        """Whether the focused widget or a container between it and the screen
        still has messages to handle (a key's consequences bubble up there)."""
        node: DOMNode | None = screen.focused
        while node is not None and node is not screen:
            if not node._message_queue.empty():
                return True
            node = node.parent
        return False

    @staticmethod
    async def _drained(screen: Screen[object], deadline: float) -> None:
        """Until the screen has handled everything posted to it so far (its queue
        is first in, first out: a callback posted now runs after all of it)."""
        done: asyncio.Future[None] = asyncio.get_running_loop().create_future()

        def finish() -> None:
            if not done.done():  # the wait may have timed out and cancelled it
                done.set_result(None)

        screen.call_later(finish)
        try:
            await asyncio.wait_for(done, max(0.0, deadline - time.monotonic()))
        except asyncio.TimeoutError:
            pass
