"""The input signals (M4; thesis 5.3 "Input signals"): one panel per channel.

Labels follow the control mode (u1/u2 in Manual, ref1/ref2 in Automatic).  The
mean is drawn as a bar (the original's slide bar): with a panel focused, up/down
nudge it progressively; a typed mean (Enter opens the window) is a step.  A click
on the on/off word toggles the wave; a click elsewhere opens the window.
"""

from __future__ import annotations

from textual import events
from textual.binding import Binding
from textual.content import Content
from textual.reactive import reactive
from textual.widgets import Static

from quadtank_tui.core.parameters import REFERENCE_SECTIONS, Parameters
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.values import fixed, fmt
from quadtank_tui.ui.labels import channel_label
from quadtank_tui.ui.widgets.sized import FitsItsSize

#: Nudge steps, normalized (0.01 = 0.1 V = 0.2 cm at the sensor).
NUDGE = 0.01
NUDGE_FINE = 0.001
_BLOCKS = " ▏▎▍▌▋▊▉█"


def bar(fraction: float, width: int) -> str:
    """A horizontal bar of `width` cells filled to `fraction` (eighths of a cell)."""
    eighths = round(max(0.0, min(1.0, fraction)) * width * 8)
    full, part = divmod(eighths, 8)
    return ("█" * full + (_BLOCKS[part] if part else "")).ljust(width)


class ChannelPanel(FitsItsSize, Static, can_focus=True):
    """One generator's mean, amplitude, period, on/off and current value."""

    BINDINGS = [
        Binding("up", "nudge(1)", "Mean +"),
        Binding("down", "nudge(-1)", "Mean -"),
        Binding("shift+up", "nudge(0.1)", "+ fine", show=False),
        Binding("shift+down", "nudge(-0.1)", "- fine", show=False),
        Binding("enter", "open", "Edit"),
        Binding("o", "wave_on_off", "Wave on/off"),
    ]

    snapshot: reactive[Snapshot | None] = reactive(None, repaint=False)

    def __init__(self, channel: int, defaults: Parameters) -> None:
        super().__init__(id=f"channel-{channel}", classes="channel")
        self.channel = channel
        self.defaults = defaults
        self._shown: tuple[str, str] = ("", "")
        self._key: tuple[object, ...] = ()

    def _val(self, p: Parameters, key: str, text: str) -> str:
        full = f"{REFERENCE_SECTIONS[self.channel - 1]}.{key}"
        return f"[i dim]{text}[/]" if p.is_modified(full, self.defaults) else text

    def watch_snapshot(self, s: Snapshot | None) -> None:
        if s is None:
            return
        # What the panel reads (the loop's time and timing change every tick).
        key = (s.params, s.control, s.w[self.channel - 1], self.content_size.width)
        if key == self._key:
            return
        self._key = key
        p = s.params
        sec = REFERENCE_SECTIONS[self.channel - 1]
        label = channel_label(self.channel, s.control)
        wave = fmt(p.get(f"{sec}.Wave"))
        mean = p.get(f"{sec}.Mean")
        period = p.get(f"{sec}.Period")
        on = p.get(f"{sec}.On")
        width = max(4, self.content_size.width - 11) if self.content_size.width else 10
        lines = [
            f"mean {self._val(p, 'Mean', fixed(mean))} [$accent]{bar(mean, width)}[/]",
            f"amp {self._val(p, 'Amplitude', fmt(p.get(f'{sec}.Amplitude')))}"
            f" per {self._val(p, 'Period', fmt(period))}{'' if wave == 'PRBS' else 's'}"
            f" [@click=screen.toggle_wave({self.channel})]{self._val(p, 'On', 'on' if on else 'off')}[/]",
            f"now  {fixed(s.w[self.channel - 1])}",
        ]
        shown = (f"{label} · {wave}", "\n".join(lines))
        if shown == self._shown:  # most samples change nothing printed here
            return
        self._shown = shown
        # Setting a border title repaints the widget even if it is the same.
        self.border_title = shown[0]
        self.border_subtitle = "i" if self.channel == 1 else "I"
        self.update(Content.from_markup(shown[1]))

    def fit_to_size(self) -> None:
        self.watch_snapshot(self.snapshot)

    def action_nudge(self, steps: float) -> None:
        self.post_message(ActionRequested(f"nudge({self.channel}, {steps * NUDGE!r})"))

    def action_open(self) -> None:
        self.post_message(ActionRequested(f"input({self.channel})"))

    def action_wave_on_off(self) -> None:
        self.post_message(ActionRequested(f"toggle_wave({self.channel})"))

    def on_click(self, event: events.Click) -> None:
        if event.style.meta.get("@click"):
            return  # the on/off word: its own action runs
        self.action_open()
