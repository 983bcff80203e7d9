"""The simulation speed the `+` and `-` keys step from.

Each press asks for the step after the current speed.  Over SSH ten presses
arrive together, and the engine applies a SetSpeed only between samples (a
process engine's snapshot comes later still): read from the snapshot, every
press of the burst saw speed x1 and asked for x2 again, so `+++` gave x5 and ten
`+` x200.  `AskedSpeed` remembers what the screen asked for until the engine has
answered every request and a snapshot shows it, so each press steps from the
previous one, as if typed half a second apart.
"""

from __future__ import annotations

import time
from typing import Callable

#: How long an answered request is trusted over a snapshot that disagrees, s: a
#: snapshot published before the command was applied can still arrive; after
#: this the snapshot wins (another client or a Reset set the speed).
TRUST = 1.0


class AskedSpeed:
    """The speed last asked for, while requests are on their way."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._asked: float | None = None
        self._pending = 0
        self._answered_at = 0.0

    def base(self, shown: float) -> float:
        """The speed the next step starts from, `shown` being the snapshot's."""
        if self._asked is None:
            return shown
        if self._pending == 0 and (shown == self._asked or self._clock() - self._answered_at > TRUST):
            self._asked = None
            return shown
        return self._asked

    def asked(self, speed: float) -> None:
        """A SetSpeed for `speed` was sent."""
        self._asked = speed
        self._pending += 1

    def answered(self, ok: bool) -> None:
        """The engine answered one request (refused: the snapshot's speed stands)."""
        self._pending = max(0, self._pending - 1)
        self._answered_at = self._clock()
        if not ok and self._pending == 0:
            self._asked = None
