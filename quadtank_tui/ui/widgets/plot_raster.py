"""The one drawing of every terminal plot (issue 43): curves rasterized on braille
dots, axes and labels around them, as rich Text.

Why not plotext any more: a plotext braille cell keeps only the series drawn
last (its character and its colour), so where y1 and ref1 shared the cells of a
settled loop the one drawn first vanished; it draws each sample as a dot and
joins them only at the resolution of the points it is given, so a step of 2 cm
read as three loose dots; and its limits leave the aspect to the widget's size,
so the 1/Ms circle was an ellipse.  Here:

- A line is a line: consecutive samples are joined dot by dot (a Bresenham walk
  on the 2 x 4 braille dots of each cell), so a step is a vertical stroke, and a
  run of samples inside one dot column draws their whole range (no sample lost
  to decimation).  A NaN breaks the line.  Without colour (NO_COLOR) the same
  walk is done on whole cells with the series' marker character.
- No series is lost where it shares a cell with another: the cell's glyph is the
  union of every series' dots there, and its colour goes to the series in turn,
  column by column (those present, in the figure's drawing order), so two curves
  lying on each other show as one two-coloured line, and a curve crossing another
  keeps its cells on either side.  A cell held by one series alone is its colour.
- `aspect` limits (`equal_aspect`) make one unit of x as long on the screen as one
  of y, for a cell `CELL_ASPECT` times as tall as it is wide: the circle stays round.
- Too few rows or columns for the curves: the plot says so, in the words given
  (`too_small`), rather than drawing something unreadable.

The mapping of a value to a dot is plot_axes' (round((dots - 1) (v - lo) / (hi -
lo)), as plotext had it), so the round labels plot_axes lays out still name the
row and column they are on.  Pure numpy and rich: no Textual.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from rich.style import Style as RichStyle
from rich.text import Text

RGB = tuple[int, int, int]

#: Dots of a braille cell: 2 across, 4 down.
XDOTS, YDOTS = 2, 4
#: A terminal cell's height over its width (most fonts: 2).
CELL_ASPECT = 2.0
#: Braille bit of the dot at (column 0..1, row 0..3 from the top) of a cell.
_BITS = np.array([[0x01, 0x08], [0x02, 0x10], [0x04, 0x20], [0x40, 0x80]], dtype=np.uint8)
#: A pen's marker that draws braille dots without colour (`quadtank log plot` in a pipe).
BRAILLE = "braille"
#: Least canvas a plot draws: fewer rows or columns say "too small" instead.
MIN_ROWS, MIN_COLUMNS = 3, 10


@dataclass(frozen=True)
class Pen:
    """How one series is drawn: its colour (None: no colour, then `marker` at cell
    resolution), and dashed (two cells drawn, two left, but a steep piece whole:
    a reference's step stays a stroke)."""

    color: RGB | None
    marker: str = "•"
    dashed: bool = False
    #: Drawn with `marker` on whole cells even in colour (a vertical rule: │).
    cells: bool = False

    @property
    def braille(self) -> bool:
        return (self.color is not None or self.marker == BRAILLE) and not self.cells

    @property
    def rich(self) -> RichStyle:
        return RichStyle() if self.color is None else RichStyle(color="rgb({},{},{})".format(*self.color))


@dataclass
class Layer:
    """One series on the figure: its points and whether they are joined."""

    x: np.ndarray
    y: np.ndarray
    pen: Pen
    joined: bool = True


@dataclass
class Figure:
    """What one plot shows: its layers in drawing order, the canvas limits (the
    values of the first and last dot's centre), labelled ticks and an x label."""

    xlim: tuple[float, float] = (0.0, 1.0)
    ylim: tuple[float, float] = (0.0, 1.0)
    xticks: list[tuple[float, str]] = field(default_factory=list)
    yticks: list[tuple[float, str]] = field(default_factory=list)
    xlabel: str | None = None
    layers: list[Layer] = field(default_factory=list)
    #: What the plot says where its canvas is too small (besides its size): the
    #: figures it shows, if it has them.
    too_small: str = "plot too small"
    #: The least canvas it is drawn on (a Nyquist plot needs more than a trend).
    min_rows: int = MIN_ROWS
    min_columns: int = MIN_COLUMNS
    #: Said in the middle of an empty plot ("no fit yet").
    note: str = ""

    def clear(self) -> None:
        """No curves (the axes stay as set)."""
        self.layers = []

    def reset(self) -> None:
        """Nothing: no curves, no ticks, no labels, no note."""
        fresh = Figure()
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(fresh, name))

    def line(self, x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray, pen: Pen) -> None:
        """Consecutive points joined."""
        self.layers.append(Layer(np.asarray(x, float), np.asarray(y, float), pen))

    def points(self, x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray, pen: Pen) -> None:
        """Points on their own (a marker: -1 on the Nyquist plot)."""
        self.layers.append(Layer(np.asarray(x, float), np.asarray(y, float), pen, joined=False))

    # --- layout ----------------------------------------------------------------------

    def label_width(self) -> int:
        return max((len(s) for _, s in self.yticks), default=1)

    def canvas_size(self, width: int, height: int) -> tuple[int, int]:
        """(columns, rows) of the canvas in a plot of width x height cells: the y
        labels and their axis line on the left, one free column on the right, the
        x axis, its labels (and the x label) below."""
        return width - self.label_width() - 2, height - 2 - (self.xlabel is not None)

    def render(self, width: int, height: int) -> Text:
        """The plot in width x height cells."""
        columns, rows = self.canvas_size(width, height)
        if self.note and not self.layers:
            return _centred([self.note], width, height)
        if columns < self.min_columns or rows < self.min_rows:
            return self._too_small(width, height, columns, rows)
        glyphs, owners = rasterize(self.layers, columns, rows, self.xlim, self.ylim)
        lw = self.label_width()
        ylabels = _tick_cells(self.yticks, self.ylim, rows * YDOTS, YDOTS)
        lines: list[Text] = []
        for r in range(rows):
            label = ylabels.get(rows - 1 - r)
            line = Text(f"{label:>{lw}}┤" if label is not None else " " * lw + "│", no_wrap=True)
            _append_cells(line, glyphs[r], owners[r], self.layers)
            line.append(" ")
            lines.append(line)
        xcols = _tick_cells(self.xticks, self.xlim, columns * XDOTS, XDOTS)
        axis = ["─"] * columns
        for c in xcols:
            axis[c] = "┬"
        lines.append(Text(" " * lw + "└" + "".join(axis) + " ", no_wrap=True))
        lines.append(Text(_centred_labels(xcols, columns, lw + 1, width), no_wrap=True))
        if self.xlabel is not None:
            lines.append(Text(self.xlabel.center(width)[:width], no_wrap=True))
        return Text("\n").join(lines)

    def _too_small(self, width: int, height: int, columns: int, rows: int) -> Text:
        need_w = max(width, width - columns + self.min_columns)
        need_h = max(height, height - rows + self.min_rows)
        return _centred(self.too_small.splitlines() + [f"(plot {width}x{height}, needs {need_w}x{need_h})"],
                        width, height)


def _centred(lines: list[str], width: int, height: int) -> Text:
    """Lines of words in the middle of width x height cells (as many as fit)."""
    out: list[str] = []
    for line in lines:  # a long line wrapped at its spaces
        words, cur = line.split(), ""
        for w in words:
            if cur and len(cur) + 1 + len(w) > width:
                out.append(cur)
                cur = w
            else:
                cur = f"{cur} {w}" if cur else w
        out.append(cur)
    out = [o[:width].center(width) for o in out][: max(1, height)]
    pad = max(0, (height - len(out)) // 2)
    return Text("\n".join([""] * pad + out), no_wrap=True)


def equal_aspect(xlim: tuple[float, float], ylim: tuple[float, float], columns: int,
                 rows: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """Limits holding xlim and ylim whose units are as long across as up on the
    screen (a circle is drawn round): the shorter range widened about its middle."""
    (x0, x1), (y0, y1) = xlim, ylim
    width_units = columns  # a cell's width is the unit of length
    height_units = rows * CELL_ASPECT
    per = max((x1 - x0) / width_units, (y1 - y0) / height_units)
    xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
    return ((xm - per * width_units / 2, xm + per * width_units / 2),
            (ym - per * height_units / 2, ym + per * height_units / 2))


# --- the raster ----------------------------------------------------------------------

def _dots(v: np.ndarray, lim: tuple[float, float], n: int) -> np.ndarray:
    """Values as fractional dot positions 0..n-1 (the dot centres' scale)."""
    lo, hi = lim
    span = hi - lo if hi != lo else 1.0
    return (v - lo) * (n - 1) / span


def _clip(x0: np.ndarray, y0: np.ndarray, x1: np.ndarray, y1: np.ndarray,
          xmax: float, ymax: float) -> tuple[np.ndarray, ...]:
    """Liang-Barsky: each segment cut to the box -0.5..max+0.5 (a segment outside
    gets t0 > t1 and is dropped by the caller)."""
    dx, dy = x1 - x0, y1 - y0
    t0, t1 = np.zeros_like(x0), np.ones_like(x0)
    for p, q in ((-dx, x0 + 0.5), (dx, xmax + 0.5 - x0), (-dy, y0 + 0.5), (dy, ymax + 0.5 - y0)):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = q / p
        parallel = p == 0
        t1 = np.where(parallel & (q < 0), -1.0, t1)  # parallel and outside
        t0 = np.where(~parallel & (p < 0), np.maximum(t0, r), t0)
        t1 = np.where(~parallel & (p > 0), np.minimum(t1, r), t1)
    return x0 + t0 * dx, y0 + t0 * dy, x0 + t1 * dx, y0 + t1 * dy, t0 <= t1


def _walk(x: np.ndarray, y: np.ndarray, xmax: int, ymax: int,
          joined: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The integer dots of a polyline (or of loose points) inside 0..xmax, 0..ymax,
    and for each whether it is on a steep piece (a step: kept by a dashed pen)."""
    ok = np.isfinite(x) & np.isfinite(y)
    if not joined or len(x) < 2:
        xi, yi = np.rint(x[ok]).astype(np.int64), np.rint(y[ok]).astype(np.int64)
        steep = np.zeros(len(xi), bool)
    else:
        seg = ok[:-1] & ok[1:]  # a NaN breaks the line
        lone = ok & ~np.concatenate([[False], seg]) & ~np.concatenate([seg, [False]])
        ax, ay, bx, by, inside = _clip(x[:-1][seg], y[:-1][seg], x[1:][seg], y[1:][seg], xmax, ymax)
        ax, ay, bx, by = ax[inside], ay[inside], bx[inside], by[inside]
        a_x, a_y, b_x, b_y = np.rint(ax), np.rint(ay), np.rint(bx), np.rint(by)
        steps = np.maximum(np.abs(b_x - a_x), np.abs(b_y - a_y)).astype(np.int64) + 1
        start = np.repeat(np.cumsum(steps) - steps, steps)
        k = np.arange(int(steps.sum())) - start
        n = np.repeat(np.maximum(steps - 1, 1), steps)
        f = k / n
        xi = np.rint(np.repeat(a_x, steps) + f * np.repeat(b_x - a_x, steps)).astype(np.int64)
        yi = np.rint(np.repeat(a_y, steps) + f * np.repeat(b_y - a_y, steps)).astype(np.int64)
        steep = np.repeat(np.abs(b_y - a_y) > np.abs(b_x - a_x), steps)
        xi = np.concatenate([xi, np.rint(x[lone]).astype(np.int64)])
        yi = np.concatenate([yi, np.rint(y[lone]).astype(np.int64)])
        steep = np.concatenate([steep, np.zeros(int(lone.sum()), bool)])
    keep = (xi >= 0) & (xi <= xmax) & (yi >= 0) & (yi <= ymax)
    return xi[keep], yi[keep], steep[keep]


def rasterize(layers: Sequence[Layer], columns: int, rows: int, xlim: tuple[float, float],
              ylim: tuple[float, float]) -> tuple[list[list[str]], list[list[int]]]:
    """Per cell (rows from the top) the character drawn and the index of the layer
    whose colour it takes (-1: empty)."""
    masks = np.zeros((len(layers), rows, columns), dtype=np.uint8)
    for n, layer in enumerate(layers):
        x, y = _dots(layer.x, xlim, columns * XDOTS), _dots(layer.y, ylim, rows * YDOTS)
        if layer.pen.braille:
            px, py, steep = _walk(x, y, columns * XDOTS - 1, rows * YDOTS - 1, layer.joined)
            col, row = px // XDOTS, rows - 1 - py // YDOTS
            bits = _BITS[YDOTS - 1 - py % YDOTS, px % XDOTS]
        else:  # a marker a cell: the walk on whole cells
            col, row, steep = _walk((x - (XDOTS - 1) / 2) / XDOTS, (y - (YDOTS - 1) / 2) / YDOTS,
                             columns - 1, rows - 1, layer.joined)
            row = rows - 1 - row
            bits = np.full(len(col), 0xFF, dtype=np.uint8)
        if layer.pen.dashed and layer.joined:
            keep = (col // 2 % 2 == 0) | steep  # flat pieces dashed, a step whole
            col, row, bits = col[keep], row[keep], bits[keep]
        np.bitwise_or.at(masks[n], (row, col), bits)
    present = masks != 0
    count = present.sum(axis=0)
    # The k-th of the layers present in a cell, k = column mod their number.
    rank = np.cumsum(present, axis=0) - 1
    turn = np.arange(columns)[None, :] % np.maximum(count, 1)
    owner = (np.where(count > 0, np.argmax(present & (rank == turn[None]), axis=0), -1) if len(layers)
             else np.full((rows, columns), -1))
    dotted = [n for n, layer in enumerate(layers) if layer.pen.braille]
    union = (np.bitwise_or.reduce(masks[dotted], axis=0) if dotted
             else np.zeros((rows, columns), np.uint8)).astype(np.int64) | 0x2800
    markers = [layer.pen.marker for layer in layers]
    glyphs: list[list[str]] = []
    for r, (owners, cells) in enumerate(zip(owner.tolist(), union.tolist())):
        glyphs.append([" " if o < 0 else chr(u) if layers[o].pen.braille else markers[o]
                       for o, u in zip(owners, cells)])
    return glyphs, owner.tolist()


def _append_cells(line: Text, glyphs: list[str], owners: list[int], layers: Sequence[Layer]) -> None:
    """A row of cells, runs of one owner as one span."""
    start = 0
    for c in range(1, len(glyphs) + 1):
        if c == len(glyphs) or owners[c] != owners[start]:
            o = owners[start]
            line.append("".join(glyphs[start:c]), layers[o].pen.rich if o >= 0 else None)
            start = c


def _tick_cells(ticks: Sequence[tuple[float, str]], lim: tuple[float, float], dots: int,
                per_cell: int) -> dict[int, str]:
    """Tick labels by the cell (from the low end) whose dots show the tick's value."""
    out: dict[int, str] = {}
    for value, label in ticks:
        d = round(float(_dots(np.array([value]), lim, dots)[0]))
        if 0 <= d < dots:
            out.setdefault(d // per_cell, label)
    return out


def _centred_labels(cols: dict[int, str], columns: int, offset: int, width: int) -> str:
    """The x labels, each centred under its tick; one that would run into the one
    before it (or off the plot) is left out."""
    row = [" "] * width
    free = 0
    for c in sorted(cols):
        label = cols[c]
        at = offset + c - (len(label) - 1) // 2
        at = min(max(at, 0), width - len(label))
        if at < free:
            continue
        row[at:at + len(label)] = list(label)
        free = at + len(label) + 1
    return "".join(row)
