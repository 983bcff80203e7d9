"""The process image (M6; thesis 5.3 "Process monitoring").

Four tanks, their widths in proportion to their diameters and their water drawn
to scale (eighth-cell blocks) with the level as a number; the two pumps with their
input; the tubes, bright where water flows, with arrows saying which way.  Pump 1
feeds tank 1 (fraction gamma1) and tank 4 (the rest), pump 2 feeds tank 2 (gamma2)
and tank 3; tanks 3 and 4 drain into 1 and 2; the gamma row says the split.  A
click on a tank or a pump opens its window.

Drawn on a character canvas sized to the widget, so it works from about 24x8
(80x24 terminals: the gammas go to the border when there is no row for them) to
large terminals.
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
        """The grid as Text, one span per run of equally styled cells: a span per
        cell would put a colour sequence before every character on the wire."""
        out = Text()
        for n, row in enumerate(self.cells):
            start = 0
            for x in range(1, len(row) + 1):
                if x == len(row) or row[x][1] != row[start][1]:
                    out.append("".join(ch for ch, _ in row[start:x]), row[start][1])
                    start = x
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


def tank_label(number: int, level: float, room: int) -> str:
    """"1:0.62", or "1:.62" in a narrow tank (80x24), or the level alone."""
    text = fixed(level, 2)
    short = text[1:] if text.startswith("0.") else text[:3]  # ".62"; "1.0" when full
    for label in (f"{number}:{text}", f"{number}:{short}", short):
        if len(label) <= room:
            return label
    return short


def gamma_text(p: object, pump: int, wide: bool) -> str:
    """A valve's split: "γ1 0.70→1 0.30→4" (how much of pump 1 goes to which tank),
    or "γ1 0.70" where there is no room."""
    g = p.get(f"SIMULATION.Valve{pump}")  # type: ignore[attr-defined]
    lower, upper = (1, 4) if pump == 1 else (2, 3)
    return f"γ{pump} {g:.2f}→{lower} {1 - g:.2f}→{upper}" if wide else f"γ{pump} {g:.2f}"


def has_gamma_row(height: int) -> bool:
    return height >= 12


def draw_tank(c: Canvas, x0: int, top: int, width: int, depth: int, level: float, number: int) -> Box:
    """An open tank: walls, water to `level` (0..1 of its height), the bottom
    border carrying "n:level"; returns its clickable box."""
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
    label = tank_label(number, level, inner)
    c.text(x0 + 1 + (inner - len(label)) // 2, bottom, label[:inner], LABEL)
    return Box(x0, top, x0 + width - 1, bottom, f"tank({number})")


def draw(snapshot: Snapshot, width: int, height: int) -> tuple[Text, list[Box]]:
    """The process image of `snapshot` in width x height cells, and its boxes."""
    c = Canvas(width, height)
    y, u, p = snapshot.y, snapshot.u, snapshot.params
    gamma_row = has_gamma_row(height)
    depth = max(1, (height - 6 - (1 if gamma_row else 0)) // 2)
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
        draw_tank(c, xs[2], top_upper, widths[2], depth, y[2], 3),
        draw_tank(c, xs[3], top_upper, widths[3], depth, y[3], 4),
        draw_tank(c, xs[0], top_lower, widths[0], depth, y[0], 1),
        draw_tank(c, xs[1], top_lower, widths[1], depth, y[1], 2),
    ]
    drain_row = top_upper + depth + 1
    for upper, x in ((2, xl), (3, xr)):  # tank 3 -> 1, tank 4 -> 2
        c.put(x, drain_row, "▼", FLOW if flowing and y[upper] > EMPTY else DRY)
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
    # Which way the water goes: up from each pump, along the tubes into the tanks.
    riser = pump_row - 1 if pump_row - 1 != drain_row else pump_row - 2
    c.put(left, riser, "▲", s1)
    c.put(right, riser, "▲", s2)
    c.put(in4 - 1, 0, "►", s1)
    c.put(in1 - 1, drain_row, "►", s1)
    c.put(in3 + 1, 1, "◄", s2)
    c.put(in2 + 1, drain_row, "◄", s2)
    # The pumps and their inputs.
    c.put(left, pump_row, "●", s1)
    c.text(left + 2, pump_row, f"P1 {fixed(u[0])}", LABEL)
    c.put(right, pump_row, "●", s2)
    label2 = f"P2 {fixed(u[1])}"
    c.text(right - 1 - len(label2), pump_row, label2, LABEL)
    boxes += [Box(0, pump_row, left + 2 + 8, pump_row, "pump(1)"),
              Box(right - 1 - len(label2), pump_row, width - 1, pump_row, "pump(2)")]
    if gamma_row:
        wide = width >= 40
        c.text(left + 2, pump_row + 1, gamma_text(p, 1, wide), DIM)
        text2 = gamma_text(p, 2, wide)
        c.text(right - 1 - len(text2), pump_row + 1, text2, DIM)
    return c.render(), boxes


class ProcessImage(Widget):
    """Renders the latest snapshot; a click on a tank or pump asks for its window.

    A new snapshot repaints the image only if the drawing differs (levels move by
    less than a printed digit or an eighth of a cell most samples)."""

    snapshot: reactive[Snapshot | None] = reactive(None, repaint=False)

    def __init__(self, caption: str = "", **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self._boxes: list[Box] = []
        self._drawn: tuple[tuple[int, int], Text] | None = None
        #: What the border's subtitle says (Setup: what the pump values are).
        self.caption = caption
        self.border_title = "Process"
        self.border_subtitle = caption

    def _draw(self) -> Text:
        """The drawing of the snapshot at the current size (cached per size)."""
        if self.snapshot is None:
            return Text("")
        size = self.content_size
        text, self._boxes = draw(self.snapshot, size.width, size.height)
        self._drawn = ((size.width, size.height), text)
        return text

    @staticmethod
    def _drawn_from(s: Snapshot) -> tuple[object, ...]:
        """What `draw` reads of a snapshot (the loop's timing changes every tick)."""
        return (s.y, s.u, s.state, s.operation, s.params.simulation)

    def watch_snapshot(self, old: Snapshot | None, new: Snapshot | None) -> None:
        size = self.content_size
        if (old is not None and new is not None and self._drawn is not None
                and self._drawn[0] == (size.width, size.height)
                and self._drawn_from(old) == self._drawn_from(new)):
            return
        before = self._drawn
        text = self._draw()
        if before is None or before[0] != self._drawn[0] or before[1] != text:  # type: ignore[index]
            self.refresh()
        self._subtitle()

    def on_resize(self) -> None:
        self._subtitle()

    def _subtitle(self) -> None:
        """The valves on the border when the image has no row for them (80x24)."""
        s = self.snapshot
        text = self.caption
        if s is not None and not has_gamma_row(self.content_size.height):
            text = " ".join(filter(None, (gamma_text(s.params, 1, False), gamma_text(s.params, 2, False), text)))
        if text != (self.border_subtitle or ""):  # setting it repaints, even unchanged
            self.border_subtitle = text

    def render(self) -> Text:
        size = self.content_size
        if self._drawn is not None and self._drawn[0] == (size.width, size.height):
            return self._drawn[1]
        return self._draw()

    def on_click(self, event: events.Click) -> None:
        offset = event.get_content_offset(self)
        if offset is None:
            return
        for box in self._boxes:
            if box.contains(offset.x, offset.y):
                self.post_message(ActionRequested(box.action))
                return
