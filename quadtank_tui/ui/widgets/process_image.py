"""The process image (M6; thesis 5.3 "Process monitoring").

Four tanks, their widths in proportion to their diameters and their water drawn
to scale (eighth-cell blocks) with the level as a number; the two pumps with their
input; the tubes, bright where water flows.  Pump 1 feeds tank 1 (fraction gamma1)
and tank 4 (the rest), pump 2 feeds tank 2 (gamma2) and tank 3; tanks 3 and 4 drain
into 1 and 2.  A click on a tank or a pump opens its window.

Drawn on a character canvas sized to the widget, so it works from about 24x9
(80x24 terminals) to large terminals.
"""

from __future__ import annotations

from dataclasses import dataclass

from rich.style import Style
from rich.text import Text
from textual import events
from textual.reactive import reactive
from textual.widget import Widget

from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.values import fixed

_FILL = " ▁▂▃▄▅▆▇█"
WATER = Style(color="dodger_blue1")
FLOW = Style(color="dodger_blue1", bold=True)
DRY = Style(color="grey42")
WALL = Style()
LABEL = Style(bold=True)
DIM = Style(dim=True)
ALARM = Style(color="white", bgcolor="red", bold=True)
#: Below this level (normalized) a tank counts as empty: nothing drains from it.
EMPTY = 1e-3


class Canvas:
    """A grid of styled characters; out-of-range writes are dropped."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.cells = [[(" ", Style())] * width for _ in range(height)]

    def put(self, x: int, y: int, ch: str, style: Style = WALL) -> None:
        if 0 <= x < self.width and 0 <= y < self.height:
            self.cells[y][x] = (ch, style)

    def text(self, x: int, y: int, s: str, style: Style = WALL) -> None:
        for i, ch in enumerate(s):
            self.put(x + i, y, ch, style)

    def hline(self, x0: int, x1: int, y: int, style: Style) -> None:
        for x in range(min(x0, x1), max(x0, x1) + 1):
            self.put(x, y, "─", style)

    def vline(self, x: int, y0: int, y1: int, style: Style) -> None:
        for y in range(min(y0, y1), max(y0, y1) + 1):
            self.put(x, y, "│", style)

    def render(self) -> Text:
        out = Text()
        for n, row in enumerate(self.cells):
            for ch, style in row:
                out.append(ch, style)
            if n < self.height - 1:
                out.append("\n")
        return out


@dataclass(frozen=True)
class Box:
    """A clickable region (cells x0..x1, y0..y1 inclusive) and its action."""

    x0: int
    y0: int
    x1: int
    y1: int
    action: str

    def contains(self, x: int, y: int) -> bool:
        return self.x0 <= x <= self.x1 and self.y0 <= y <= self.y1


def draw_tank(c: Canvas, x0: int, top: int, width: int, depth: int, level: float, number: int,
              spilling: bool = False) -> Box:
    """An open tank: walls, water to `level` (0..1 of its height), the bottom
    border carrying "n:level" (white on red while it spills); returns its box."""
    inner = width - 2
    units = round(max(0.0, min(1.0, level)) * depth * 8)
    for row in range(depth):
        y = top + depth - 1 - row
        c.put(x0, y, "│")
        c.put(x0 + width - 1, y, "│")
        fill = max(0, min(8, units - 8 * row))
        c.text(x0 + 1, y, _FILL[fill] * inner, WATER)
    bottom = top + depth
    c.text(x0, bottom, "└" + "─" * inner + "┘")
    short = fixed(level, 2)[-3:] if level < 0.995 else "1.0"  # ".00" would read as empty
    label = f"{number}:{fixed(level, 2)}" if inner >= 6 else short
    c.text(x0 + 1 + (inner - len(label)) // 2, bottom, label[:inner], ALARM if spilling else LABEL)
    return Box(x0, top, x0 + width - 1, bottom, f"tank({number})")


def draw(snapshot: Snapshot, width: int, height: int,
         spilling: frozenset[int] = frozenset()) -> tuple[Text, list[Box]]:
    """The process image of `snapshot` in width x height cells (the tanks in
    `spilling` marked), and its boxes."""
    c = Canvas(width, height)
    y, u, p = snapshot.y, snapshot.u, snapshot.params
    has_gamma_row = height >= 12
    depth = max(1, (height - 6 - (1 if has_gamma_row else 0)) // 2)
    if width < 22 or height < 8:
        c.text(0, 0, "y " + " ".join(fixed(v, 2) for v in y))
        c.text(0, 1, "u " + " ".join(fixed(v, 2) for v in u))
        return c.render(), [Box(0, 0, width - 1, 0, "tank(1)"), Box(0, 1, width - 1, 1, "pump(1)")]
    diam = [p.get(f"SIMULATION.Diameter{n}") for n in range(1, 5)]
    maxw = max(6, min(14, (width - 8) // 2 - 1))
    widths = [max(4, min(maxw, round(maxw * d / max(diam)))) for d in diam]
    xl, xr = 4 + maxw // 2, width - 5 - maxw // 2
    xs = [xl - widths[0] // 2, xr - widths[1] // 2, xl - widths[2] // 2, xr - widths[3] // 2]
    top_upper, top_lower = 2, 2 + depth + 2
    pump_row = top_lower + depth + 1
    flowing = snapshot.state == "Run" or snapshot.operation == "Active"
    pump_style = [FLOW if flowing and v > EMPTY else DRY for v in u]
    boxes = [
        draw_tank(c, xs[2], top_upper, widths[2], depth, y[2], 3, 3 in spilling),
        draw_tank(c, xs[3], top_upper, widths[3], depth, y[3], 4, 4 in spilling),
        draw_tank(c, xs[0], top_lower, widths[0], depth, y[0], 1, 1 in spilling),
        draw_tank(c, xs[1], top_lower, widths[1], depth, y[1], 2, 2 in spilling),
    ]
    drain_row = top_upper + depth + 1
    for upper, x in ((2, xl), (3, xr)):  # tank 3 -> 1, tank 4 -> 2
        c.put(x, drain_row, "│", FLOW if flowing and y[upper] > EMPTY else DRY)
    # Pump 1: up the left side, into tank 1 and across the top into tank 4.
    left, right = 1, width - 2
    in1, in4 = xs[0] + 1, xs[3] + 1
    s1, s2 = pump_style
    c.vline(left, 0, pump_row - 1, s1)
    c.put(left, 0, "┌", s1)
    c.hline(left + 1, in4 - 1, 0, s1)
    c.put(in4, 0, "┐", s1)
    c.put(in4, 1, "│", s1)
    c.put(left, drain_row, "├", s1)
    c.hline(left + 1, in1 - 1, drain_row, s1)
    c.put(in1, drain_row, "┐", s1)
    # Pump 2: up the right side, into tank 2 and across into tank 3.
    in2, in3 = xs[1] + widths[1] - 2, xs[2] + widths[2] - 2
    c.vline(right, 1, pump_row - 1, s2)
    c.put(right, 1, "┐", s2)
    c.hline(in3 + 1, right - 1, 1, s2)
    c.put(in3, 1, "┌", s2)
    c.put(in4, 1, "┼", s1)  # pump 1's drop to tank 4 crosses pump 2's tube
    c.put(right, drain_row, "┤", s2)
    c.hline(in2 + 1, right - 1, drain_row, s2)
    c.put(in2, drain_row, "┌", s2)
    # The pumps and their inputs.
    c.put(left, pump_row, "●", s1)
    c.text(left + 2, pump_row, f"P1 {fixed(u[0])}", LABEL)
    c.put(right, pump_row, "●", s2)
    label2 = f"P2 {fixed(u[1])}"
    c.text(right - 1 - len(label2), pump_row, label2, LABEL)
    boxes += [Box(0, pump_row, left + 2 + 8, pump_row, "pump(1)"),
              Box(right - 1 - len(label2), pump_row, width - 1, pump_row, "pump(2)")]
    if has_gamma_row:
        g1, g2 = p.get("SIMULATION.Valve1"), p.get("SIMULATION.Valve2")
        c.text(left + 2, pump_row + 1, f"γ1 {g1:.2f}", DIM)
        text2 = f"γ2 {g2:.2f}"
        c.text(right - 1 - len(text2), pump_row + 1, text2, DIM)
    return c.render(), boxes


class ProcessImage(Widget):
    """Renders the latest snapshot; a click on a tank or pump asks for its window."""

    snapshot: reactive[Snapshot | None] = reactive(None)
    #: Tanks that overflow now (the screen works it out, see spilling_tanks).
    spilling: reactive[frozenset[int]] = reactive(frozenset())

    def __init__(self, **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self._boxes: list[Box] = []
        self.border_title = "Process"

    def render(self) -> Text:
        if self.snapshot is None:
            return Text("")
        size = self.content_size
        text, self._boxes = draw(self.snapshot, size.width, size.height, self.spilling)
        return text

    def on_click(self, event: events.Click) -> None:
        offset = event.get_content_offset(self)
        if offset is None:
            return
        for box in self._boxes:
            if box.contains(offset.x, offset.y):
                self.post_message(ActionRequested(box.action))
                return
