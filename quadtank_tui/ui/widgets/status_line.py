"""The two lines at the top of the Main screen: the modes (clickable, the current
ones highlighted) and the loop's state in numbers.

Line 1 is the original's Mode box and Run/Pause/Reset buttons; line 2 is what a
student over SSH needs to trust the picture: process time, sampling time, speed
(asked and, when the machine cannot keep it, held), how old the last sample is (a
stalled loop shows), logging progress.

A line is repainted only when its text changes: the screen hands a snapshot down on
every refresh tick, and over SSH every repaint costs the link (issue 17).
"""

from __future__ import annotations

from typing import Any

import math
from collections import deque

from textual.content import Content
from textual.geometry import Region
from textual.reactive import reactive
from textual.widget import Widget

from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.labels import log_state

#: (key, action, label, is-current test) of the clickable mode words.
_MODES = (
    (("s", "simul", "Simul", lambda s: s.operation == "Simul"),
     ("A", "active", "Active", lambda s: s.operation == "Active")),
    (("r", "run", "Run", lambda s: s.state == "Run"),
     ("p", "pause", "Pause", lambda s: s.state == "Pause"),
     ("R", "reset", "Reset", lambda s: False)),
    (("m", "manual", "Manual", lambda s: s.control == "Manual"),
     ("a", "automatic", "Auto", lambda s: s.control == "Automatic")),
    (("l", "logging", "Log", lambda s: s.log.active),
     ("q", "exit", "Exit", lambda s: False)),
)


#: The schedule's slots (samples + skipped deadlines) the held speed is measured over.
SPEED_SLOTS = 20
#: Below this fraction of the asked speed the status line says what is held.
SPEED_HELD = 0.99


class SpeedMeter:
    """The speed a virtual clock really keeps.  A clock that cannot keep up skips
    its deadlines (LoopStats.skipped), so over the last slots the held speed is
    the asked one times samples / (samples + skipped): no wall clock needed, and
    the same on a loaded machine as in a test."""

    def __init__(self, span: int = 64) -> None:
        self._seen: deque[tuple[float, int, int]] = deque(maxlen=span)

    def add(self, s: Snapshot) -> None:
        entry = (s.speed, s.stats.samples, s.stats.skipped)
        if not self._seen or self._seen[-1] != entry:
            if self._seen and self._seen[-1][0] != s.speed:
                self._seen.clear()  # a new speed: measure afresh
            self._seen.append(entry)

    def held(self) -> float | None:
        """The speed held over the snapshots kept (a few seconds of the screen's
        ticks), once they span SPEED_SLOTS slots (None before)."""
        if len(self._seen) < 2:
            return None
        speed, samples, skipped_now = self._seen[-1]
        done, skipped = samples - self._seen[0][1], skipped_now - self._seen[0][2]
        if done + skipped < SPEED_SLOTS:
            return None
        return speed * done / (done + skipped)


class StatusLine(Widget):
    """Modes and loop numbers from the latest snapshot; `age` is the wall-clock
    time since the last sample, s (the screen measures it)."""

    snapshot: reactive[Snapshot | None] = reactive(None, repaint=False)
    age: reactive[float] = reactive(0.0, repaint=False)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.speed = SpeedMeter()
        self._lines: tuple[object, ...] = (None, None)

    def watch_snapshot(self, s: Snapshot | None) -> None:
        if s is not None:
            self.speed.add(s)
        self._repaint_changed()

    def watch_age(self) -> None:
        self._repaint_changed()

    def _repaint_changed(self) -> None:
        """Repaint the lines whose text changed, and only those."""
        s = self.snapshot
        lines = (None, None) if s is None else (self._modes_key(s), self.numbers(s))
        changed = [n for n in (0, 1) if lines[n] != self._lines[n]]
        self._lines = lines
        if len(changed) == 2 or s is None:
            self.refresh()
        elif changed:
            self.refresh(Region(0, changed[0], max(1, self.size.width), 1))

    @staticmethod
    def _modes_key(s: Snapshot) -> tuple[object, ...]:
        """What line 1 shows."""
        return (s.operation, s.state, s.control, s.log.active, s.active_available, s.fault)

    def render(self) -> Content:
        s = self.snapshot
        if s is None:
            return Content("starting...")
        groups = []
        for group in _MODES:
            words = []
            for key, action, label, current in group:
                unavailable = action == "active" and not s.active_available
                style = "reverse bold" if current(s) else ("dim strike" if unavailable else "")
                words.append(Content.from_markup(
                    f"[dim]{key}[/] [{style} @click=screen.{action}]{label}[/]" if style else
                    f"[dim]{key}[/] [@click=screen.{action}]{label}[/]"))
            groups.append(Content(" ").join(words))
        line1 = Content(" ") + Content(" │ ").join(groups)
        if s.fault:
            line1 += Content.from_markup(" [b $error]fault: $fault[/]", fault=s.fault)
        return Content("\n").join([line1, Content(" " + self.numbers(s))])

    def numbers(self, s: Snapshot) -> str:
        parts = [f"t {s.t:7.1f} s", f"Ts {s.params.tsamp:g} s"]
        if s.operation == "Simul" and not s.realtime:
            parts.append(self.speed_text(s))
        else:  # a real-time clock: a skipped deadline is a sample missed on the rig
            parts.append(f"overruns {s.stats.overruns}")
        if s.state == "Run" and self.age > max(1.0, 3 * s.params.tsamp):
            parts.append(f"last sample {self.age:.1f} s ago")
        parts.append(f"log {log_state(s.log)}" + (f" {100 * s.log.progress:.0f}%" if s.log.active else ""))
        parts.append(s.backend)
        parts.extend(s.alarms)
        if s.faults:  # injected in Simul (core.faults): a student should know the process is broken
            parts.append(f"faults: {s.faults}")
        return "  ".join(parts)

    def speed_text(self, s: Snapshot) -> str:
        """"speed x16", or "speed x16 asked, x15.6 held" when the machine cannot keep
        it (the loop skips deadlines: process time runs slower than asked)."""
        if math.isinf(s.speed):
            return "speed max"
        held = self.speed.held()
        if held is not None and held < SPEED_HELD * s.speed:
            return f"speed x{s.speed:g} asked, x{held:.3g} held"
        return f"speed x{s.speed:g}"
