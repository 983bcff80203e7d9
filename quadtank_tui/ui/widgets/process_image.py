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

Another plant (a `.par` PLANT section) is drawn from its layout (core.plants):
its tanks in their columns and rows with the water to scale of their height, one
pump or two up the sides into the tanks they feed, drains below, an orifice between
tanks side by side ("◀"/"▶" the way the water runs).
"""

from __future__ import annotations

from typing import Any

from dataclasses import dataclass

from rich.style import Style
from rich.text import Text
from textual import events
from textual.reactive import reactive

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.values import fixed
from quadtank_tui.ui.widgets.sized import FitsItsSize

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


def gamma_text(p: Parameters, pump: int, wide: bool) -> str:
    """A valve's split: "γ1 0.70→1 0.30→4" (how much of pump 1 goes to which tank),
    or "γ1 0.70" where there is no room."""
    g = p.get(f"SIMULATION.Valve{pump}")
    lower, upper = (1, 4) if pump == 1 else (2, 3)
    return f"γ{pump} {g:.2f}→{lower} {1 - g:.2f}→{upper}" if wide else f"γ{pump} {g:.2f}"


def has_gamma_row(height: int) -> bool:
    return height >= 12


def draw_tank(c: Canvas, x0: int, top: int, width: int, depth: int, level: float, number: int,
              shown: float | None = None, spilling: bool = False) -> Box:
    """An open tank: walls, water to `level` (0..1 of its height), the bottom
    border carrying "n:level" (`shown` instead of the level when given: the
    normalized reading of a tank whose sensor does not span 10 V; white on red
    while it spills); returns its clickable box."""
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
    label = tank_label(number, level if shown is None else shown, inner)
    c.text(x0 + 1 + (inner - len(label)) // 2, bottom, label[:inner], ALARM if spilling else LABEL)
    return Box(x0, top, x0 + width - 1, bottom, f"tank({number})")


def draw(snapshot: Snapshot, width: int, height: int,
         spilling: frozenset[int] = frozenset()) -> tuple[Text, list[Box]]:
    """The process image of `snapshot` in width x height cells (the tanks in
    `spilling` marked), and its boxes."""
    if snapshot.params.process is not None and width >= 22 and height >= 8:
        return draw_plant(snapshot, width, height)
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
        draw_tank(c, xs[2], top_upper, widths[2], depth, y[2], 3, spilling=3 in spilling),
        draw_tank(c, xs[3], top_upper, widths[3], depth, y[3], 4, spilling=4 in spilling),
        draw_tank(c, xs[0], top_lower, widths[0], depth, y[0], 1, spilling=1 in spilling),
        draw_tank(c, xs[1], top_lower, widths[1], depth, y[1], 2, spilling=2 in spilling),
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


def draw_plant(snapshot: Snapshot, width: int, height: int) -> tuple[Text, list[Box]]:
    """Another plant, drawn from its layout (core.plants.base.Layout)."""
    plant = snapshot.params.process_plant()
    lay = plant.layout()
    c = Canvas(width, height)
    y, u = snapshot.y, snapshot.u
    flowing = snapshot.state == "Run" or snapshot.operation == "Active"
    cols, rows = lay.columns, lay.rows
    depth = max(1, (height - 4) // rows - 2)
    tw = max(6, min(14, (width - 6) // cols - 4))
    gap = (width - 4 - cols * tw) // (cols + 1)
    x_of = [2 + gap + col * (tw + gap) for col in range(cols)]
    top_of = [2 + (rows - 1 - row) * (depth + 2) for row in range(rows)]
    boxes: list[Box] = []
    fraction = []
    for t in lay.tanks:  # level as a fraction of the tank height: reading x 10 V / full-scale volts
        fraction.append(y[t.state] * 10.0 / plant.outputs[t.state].hi if t.state < 4 else 0.0)
        boxes.append(draw_tank(c, x_of[t.column], top_of[t.row], tw, depth, fraction[-1], t.state + 1,
                               shown=y[t.state]))
    by_state = {t.state: t for t in lay.tanks}
    for pipe in lay.pipes:
        src = by_state[pipe.source]
        wet = flowing and fraction[lay.tanks.index(src)] > EMPTY
        bottom = top_of[src.row] + depth
        if pipe.target is None:  # a drain to the basin
            c.put(x_of[src.column] + tw // 2, bottom + 1, "│", FLOW if wet else DRY)
            continue
        dst = by_state[pipe.target]
        if dst.row < src.row:  # drips into the tank below
            c.vline(x_of[src.column] + tw // 2, bottom + 1, top_of[dst.row] - 1, FLOW if wet else DRY)
        else:  # side by side: an orifice near the base, the water runs to the lower level
            x0, x1 = x_of[src.column] + tw, x_of[dst.column] - 1
            forward = y[pipe.source] >= y[pipe.target]
            c.hline(x0, x1, bottom - 1, FLOW if flowing else DRY)
            c.put((x0 + x1) // 2, bottom - 1, "▶" if forward else "◀", FLOW if flowing else DRY)
    pump_row = height - 1
    for k, pump in enumerate(lay.pumps):
        style = FLOW if flowing and u[pump.input] > EMPTY else DRY
        side = 1 if k == 0 else width - 2
        rows_used = []
        for state, _share in pump.feeds:
            t = by_state[state]
            inlet = x_of[t.column] + (1 if k == 0 else tw - 2)
            top = top_of[t.row]
            # into a top-row tank the two pumps' tubes take the two free rows above it;
            # into a lower tank the row between the tank rows
            row = top - 1 - k if t.row == rows - 1 else top - 1
            rows_used.append(row)
            c.hline(min(side, inlet) + 1, max(side, inlet) - 1, row, style)
            c.put(inlet, row, "┐" if k == 0 else "┌", style)
            for yy in range(row + 1, top):
                c.put(inlet, yy, "│", style)
        top_row = min(rows_used, default=pump_row)
        c.vline(side, top_row, pump_row - 1, style)
        for row in rows_used:
            c.put(side, row, ("┌" if k == 0 else "┐") if row == top_row else ("├" if k == 0 else "┤"), style)
        c.put(side, pump_row, "●", style)
        label = f"P{pump.input + 1} {fixed(u[pump.input])}"
        lx = side + 2 if k == 0 else side - 1 - len(label)
        c.text(lx, pump_row, label, LABEL)
        boxes.append(Box(min(lx, side), pump_row, max(lx + len(label), side), pump_row, f"pump({pump.input + 1})"))
    return c.render(), boxes


class ProcessImage(FitsItsSize):
    """Renders the latest snapshot; a click on a tank or pump asks for its window.

    A new snapshot repaints the image only if the drawing differs (levels move by
    less than a printed digit or an eighth of a cell most samples)."""

    snapshot: reactive[Snapshot | None] = reactive(None, repaint=False)
    #: Tanks that overflow now (the screen works it out, see spilling_tanks).
    spilling: reactive[frozenset[int]] = reactive(frozenset())

    def __init__(self, caption: str = "", **kwargs: Any) -> None:
        super().__init__(**kwargs)
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
        text, self._boxes = draw(self.snapshot, size.width, size.height, self.spilling)
        self._drawn = ((size.width, size.height), text)
        return text

    def watch_spilling(self) -> None:
        """An overflow starting or ending changes a label: draw again."""
        self._draw()
        self.refresh()

    @staticmethod
    def _drawn_from(s: Snapshot) -> tuple[object, ...]:
        """What `draw` reads of a snapshot (the loop's timing changes every tick)."""
        return (s.y, s.u, s.state, s.operation, s.params.simulation, s.params.process)

    def watch_snapshot(self, old: Snapshot | None, new: Snapshot | None) -> None:
        size = self.content_size
        if (old is not None and new is not None and self._drawn is not None
                and self._drawn[0] == (size.width, size.height)
                and self._drawn_from(old) == self._drawn_from(new)):
            return
        before = self._drawn
        self._draw()
        if before is None or before != self._drawn:  # another size, or other text
            self.refresh()
        self._subtitle()

    def fit_to_size(self) -> None:
        self._subtitle()

    def _subtitle(self) -> None:
        """The valves on the border when the image has no row for them (80x24)."""
        s = self.snapshot
        text = self.caption
        if s is not None and s.params.process is None and not has_gamma_row(self.content_size.height):
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
