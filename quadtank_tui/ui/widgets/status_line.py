"""The two lines at the top of the Main screen: the modes (clickable, the current
ones highlighted) and the loop's state in numbers.

Line 1 is the original's Mode box and Run/Pause/Reset buttons; line 2 is what a
student over SSH needs to trust the picture: process time, sampling time, speed,
overruns, how old the last sample is (a stalled loop shows), logging progress.
"""

from __future__ import annotations

from textual.content import Content
from textual.reactive import reactive
from textual.widget import Widget

from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.windows.logging import log_state

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


class StatusLine(Widget):
    """Modes and loop numbers from the latest snapshot; `age` is the wall-clock
    time since the last sample, s (the screen measures it)."""

    snapshot: reactive[Snapshot | None] = reactive(None)
    age: reactive[float] = reactive(0.0)

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
            parts.append("speed max" if s.speed == float("inf") else f"speed x{s.speed:g}")
        parts.append(f"overruns {s.stats.overruns}")
        if s.state == "Run" and self.age > max(1.0, 3 * s.params.tsamp):
            parts.append(f"last sample {self.age:.1f} s ago")
        parts.append(f"log {log_state(s.log)}" + (f" {100 * s.log.progress:.0f}%" if s.log.active else ""))
        parts.append(s.backend)
        parts.extend(s.alarms)
        if s.faults:  # injected in Simul (core.faults): a student should know the process is broken
            parts.append(f"faults: {s.faults}")
        return "  ".join(parts)
