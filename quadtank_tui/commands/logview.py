"""`quadtank log plot` and `quadtank log compare`: old runs in a terminal.

plot draws chosen columns of a `.log` against time with the interface's plot kit
(ui/widgets/plot_raster.py), the y axis laid out as the live trends lay it out (round values, each label on the row whose
value it names: ui/widgets/trends.py `y_axis`) and the time axis in round
seconds.  compare prints both loops' step figures of two logs side by side: the
last reference step, rise time, overshoot, settling time, IAE and final error
(core/metrics.py, the figures the headless run prints).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
from typing import TYPE_CHECKING, Sequence

from quadtank_tui.commands import UsageError, warn

if TYPE_CHECKING:
    import numpy as np

    from quadtank_tui.files.log_reader import LogData

#: The plot's default size when the terminal's is unknown (a pipe).
DEFAULT_SIZE = (100, 25)
#: Columns between two time ticks, about.
TICK_SPACING = 14
#: The largest plot, characters: wider than any terminal (`--width 100000000`
#: took 60 s and 11.5 GB to fail with a MemoryError, `--height 10000000` 3.8 GB).
MAX_WIDTH, MAX_HEIGHT = 2000, 1000
#: The largest log `log plot` reads: 9.6 h of 50 ms samples; a 200 MB log (4.2
#: million rows) took 166 s and 2.55 GB.  Reading costs about 17 us a row.
MAX_PLOT_BYTES = 64_000_000


def add_parsers(logsub: argparse._SubParsersAction) -> None:
    """`plot` and `compare` under `quadtank log`."""
    plot = logsub.add_parser("plot", help="draw a log's signals against time in the terminal")
    plot.add_argument("file", metavar="FILE")
    plot.add_argument("--vars", nargs="+", metavar="NAME",
                      help="the columns to draw (default: all but t)")
    plot.add_argument("--width", type=int, metavar="W", help="columns (default: the terminal's)")
    plot.add_argument("--height", type=int, metavar="H", help="rows (default: 25)")
    plot.set_defaults(handler=cmd_plot)
    compare = logsub.add_parser("compare", help="both loops' step figures of two logs side by side")
    compare.add_argument("first", metavar="A.log")
    compare.add_argument("second", metavar="B.log")
    compare.set_defaults(handler=cmd_compare)


def _read(path: str, max_bytes: tuple[int, str] | None = None) -> LogData:
    from quadtank_tui.files.log_reader import read_log

    log = read_log(path, max_bytes=max_bytes)
    warn(log.warnings)
    return log


def times(log: LogData, path: str) -> np.ndarray:
    """Each row's time, s: the `t` column if logged, else row x TSamp."""
    import numpy as np

    if "t" in log.variables:
        return log["t"]
    if log.tsamp is None:
        raise UsageError(f"{path}: neither a t column nor a TSamp in the header: the times are unknown")
    return np.arange(log.rows) * log.tsamp


# --- plot -----------------------------------------------------------------------------------

def cmd_plot(args: argparse.Namespace) -> int:
    for option, value, most in (("--width", args.width, MAX_WIDTH), ("--height", args.height, MAX_HEIGHT)):
        if value is not None and not 0 < value <= most:
            raise UsageError(f"{option} must be 1..{most} characters, got {value}")
    log = _read(args.file, (MAX_PLOT_BYTES, "log plot"))
    names = tuple(args.vars) if args.vars else tuple(n for n in log.variables if n != "t")
    missing = [n for n in names if n not in log.variables]
    if missing:
        raise UsageError(f"{args.file}: no column {' '.join(missing)} (logged: {' '.join(log.variables)})")
    if not names:
        raise UsageError(f"{args.file}: nothing to draw but t")
    if log.rows < 2:
        raise UsageError(f"{args.file}: {log.rows} row(s): a plot needs two")
    size = shutil.get_terminal_size(DEFAULT_SIZE)
    width = args.width or size.columns
    height = args.height or DEFAULT_SIZE[1]
    if width < 30 or height < 8:
        raise UsageError(f"a plot needs at least 30 x 8 characters, got {width} x {height}")
    colour = sys.stdout.isatty() and not os.environ.get("NO_COLOR")
    print(render_plot(log, times(log, args.file), names, width, height, colour=colour, title=args.file))
    return 0


def render_plot(log: LogData, t: np.ndarray, names: Sequence[str], width: int, height: int, *,
                colour: bool, title: str) -> str:
    """A title line naming each curve in its colour, then the plot, `height` rows,
    drawn by the interface's plot kit (ui/widgets/plot_raster.py: samples joined
    into lines, no curve lost where curves share a cell).

    Without colour (a pipe, NO_COLOR) several curves draw with a character each
    (* + o x, references ·), named in the title; one curve keeps braille.  The
    references (r1, r2) are drawn first and dashed, the levels over them."""
    import io

    from rich.console import Console

    from quadtank_tui.ui.colours import BLUE, CYAN, GREEN, GREY, MAGENTA, ORANGE, RED, SIGNALS
    from quadtank_tui.ui.plot_axes import AXIS_ROWS, y_axis
    from quadtank_tui.ui.widgets.plot_raster import BRAILLE, Figure, Pen
    from quadtank_tui.ui.widgets.trend_style import DOTTED_MARKER, MARKERS

    # The trends' own colours (as on a dark terminal), so a curve has the same
    # colour here as on Main; other columns take the palette's hues in turn.
    spare = (BLUE, RED, GREEN, ORANGE, CYAN, MAGENTA, GREY)
    palette = [SIGNALS.get(n.replace("r", "ref") if n in ("r1", "r2") else n, h).dark
               for n, h in zip(names, spare * (len(names) // len(spare) + 1))]
    reference = [n in ("r1", "r2") for n in names]
    solid = [n for n, ref in zip(names, reference) if not ref]
    markers = {n: (DOTTED_MARKER if ref else MARKERS[solid.index(n) % len(MARKERS)]) for n, ref in zip(names, reference)}
    marked = not colour and len(names) > 1
    fig = Figure()
    for i in sorted(range(len(names)), key=lambda i: not reference[i]):
        name = names[i]
        rows = envelope(log[name], 2 * width)  # the same line at the dots across, far fewer points
        fig.line(t[rows], log[name][rows], Pen(palette[i] if colour else None,
                                               markers[name] if marked else BRAILLE, dashed=reference[i]))
    values = [float(v) for n in names for v in (log[n].min(), log[n].max())]
    axis = y_axis(min(values), max(values), height - 1 - AXIS_ROWS)
    fig.ylim = (axis.lo, axis.hi)
    fig.yticks = list(zip(axis.ticks, axis.labels))
    t0, t1 = float(t[0]), float(t[-1])
    fig.xlim = (t0, t1)
    fig.xticks = [(v, f"{v:g}") for v in time_ticks(t0, t1, width)]
    text = fig.render(width, height - 1)
    if colour:
        out = io.StringIO()
        Console(file=out, force_terminal=True, color_system="truecolor", width=width, legacy_windows=False,
                soft_wrap=True).print(text, end="")
        drawing = out.getvalue()
    else:
        drawing = text.plain
    lines = [line.rstrip() for line in drawing.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    legend = "  ".join(f"{markers[n]} {n}" if marked else _in_colour(n, c, colour) for n, c in zip(names, palette))
    return "\n".join([f"{title}  {legend}  (t in s)", *lines])


def envelope(y: np.ndarray, bins: int) -> np.ndarray:
    """The rows of `y` that draw the same line at `bins` dots across: the first and
    last, and each bin's lowest and highest in time order (a spike of one row
    stays).  plotext costs about a millisecond a thousand points, and the memory
    of a Python float each: every row of a long log took minutes and gigabytes."""
    import numpy as np

    n = len(y)
    size = -(-n // max(1, bins))
    if size <= 2:
        return np.arange(n)
    whole = (n // size) * size
    blocks = y[:whole].reshape(-1, size)
    starts = np.arange(0, whole, size)
    picks = [np.array([0, n - 1]), starts + np.argmin(np.where(np.isnan(blocks), np.inf, blocks), axis=1),
             starts + np.argmax(np.where(np.isnan(blocks), -np.inf, blocks), axis=1)]
    if whole < n:
        tail = y[whole:]
        picks.append(whole + np.array([int(np.nanargmin(tail)) if not np.isnan(tail).all() else 0,
                                      int(np.nanargmax(tail)) if not np.isnan(tail).all() else 0]))
    return np.unique(np.concatenate(picks))


def _in_colour(text: str, rgb: tuple[int, int, int], colour: bool) -> str:
    if not colour:
        return text
    r, g, b = rgb
    return f"\x1b[38;2;{r};{g};{b}m{text}\x1b[0m"


def time_ticks(t0: float, t1: float, width: int) -> list[float]:
    """Round times (multiples of 1, 2, 2.5 or 5 x 10^n s) about TICK_SPACING
    columns apart, within t0..t1."""
    span = max(t1 - t0, 1e-9)
    wanted = max(2, width // TICK_SPACING)
    exponent = math.floor(math.log10(span / wanted))
    for step in (m * 10.0 ** e for e in (exponent, exponent + 1) for m in (1, 2, 2.5, 5)):
        if span / step <= wanted:
            break
    first = math.ceil(t0 / step - 1e-9)
    return [round(k * step, 9) for k in range(first, math.floor(t1 / step + 1e-9) + 1)]


# --- compare --------------------------------------------------------------------------------

def cmd_compare(args: argparse.Namespace) -> int:
    logs = [(path, _read(path)) for path in (args.first, args.second)]
    print(compare_text(logs))
    return 0


def _seconds(x: float | None, missing: str = "-") -> str:
    if x is None:
        return missing
    return f"{x:.0f} s" if abs(x) >= 100 else f"{x:.3g} s"


def loop_column(log: LogData, path: str, loop: int) -> list[str]:
    """The figures of loop `loop` (y and r of that number) of one log, as cells."""
    from quadtank_tui.core.metrics import loop_metrics, rise_time

    y, r = f"y{loop}", f"r{loop}"
    if y not in log.variables or r not in log.variables:
        absent = " and ".join(n for n in (y, r) if n not in log.variables)
        return [f"{absent} not logged"] + ["-"] * 5
    t = times(log, path)
    m = loop_metrics(t, log[y], log[r])
    if m.step is None:
        step = "none"
    else:
        step = f"{m.step:+.3f} at {_seconds(m.step_time)}"
    over = "-" if m.overshoot is None else f"{m.overshoot:.1f} %"
    settling = "-" if m.step is None else _seconds(m.settling_time, "not settled")
    rise = "-" if m.step is None else _seconds(rise_time(t, log[y], log[r]), "not reached")
    final = round(m.final_error, 5) + 0.0  # no "-0.00000"
    return [step, rise, over, settling, f"{m.iae:.3f}", f"{final:+.5f}"]


ROWS = ("last step", "rise 10-90 %", "overshoot", "settling 2 %", "IAE", "final error")


def compare_text(logs: Sequence[tuple[str, LogData]]) -> str:
    """The two logs' figures, one column each."""
    from quadtank_tui.files.log_writer import format_tsamp

    table: list[list[str]] = [["", *(path for path, _ in logs)]]
    table.append(["rows x TSamp", *(f"{log.rows} x " + ("?" if log.tsamp is None else f"{format_tsamp(log.tsamp)} s")
                                    for _, log in logs)])
    for loop in (1, 2):
        table.append([f"loop {loop} (y{loop}, r{loop})", *([""] * len(logs))])
        columns = [loop_column(log, path, loop) for path, log in logs]
        for i, label in enumerate(ROWS):
            table.append([f"  {label}", *(col[i] for col in columns)])
    widths = [max(len(row[c]) for row in table) for c in range(len(table[0]))]
    return "\n".join("   ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in table)
