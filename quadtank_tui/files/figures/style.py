"""How every figure looks, and how it is written so that the same data give the
same bytes: matplotlib's own DejaVu fonts (shipped with it, so no machine's fonts
change a figure), no date or version in the metadata, a fixed SVG hash salt.

Colours are Okabe and Ito's palette for colour-blind readers; a run of several
files gets one colour per run and the variables of a panel differ by line style,
so a figure printed in grey still tells them apart.  References are drawn dashed,
thinner and under the outputs: once y sits on r the output still shows.
"""

from __future__ import annotations

import functools
import io
import threading
from pathlib import Path
from typing import Any, Callable, Iterator, ParamSpec, TypeVar
from contextlib import contextmanager

import matplotlib
from matplotlib.figure import Figure

from quadtank_tui.files.atomic import atomic_write_bytes
from quadtank_tui.files.figures import figure_format

#: Written into each file as the program that made it (no version: a figure made
#: by the next release of the same data is the same file).
CREATOR = "quadtank-tui"

#: Okabe-Ito: blue, vermillion, bluish green, orange, reddish purple, sky blue, yellow, black.
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#E69F00", "#CC79A7", "#56B4E9", "#F0E442", "#000000")
#: A signal's colour when one run is drawn (the same signal, the same colour, in every figure).
SIGNAL_COLOURS = {"y1": PALETTE[0], "y2": PALETTE[1], "y3": PALETTE[2], "y4": PALETTE[3],
                  "u1": PALETTE[4], "u2": PALETTE[5], "r1": PALETTE[0], "r2": PALETTE[1]}
#: Model, band and guide lines.
MODEL_COLOUR = "#000000"
GUIDE_COLOUR = "#666666"
BAND_COLOUR = "#BBBBBB"
#: Line styles of the variables of one panel, in order (references always dashed).
LINE_STYLES = ("-", "-.", ":", (0, (5, 1, 1, 1, 1, 1)))
REFERENCE_STYLE: dict[str, Any] = {"linestyle": "--", "linewidth": 1.0, "alpha": 0.75, "zorder": 1}
OUTPUT_STYLE: dict[str, Any] = {"linewidth": 1.6, "zorder": 2}

#: rcParams of every figure: matplotlib's defaults are kept where they are fine.
RC: dict[str, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 9.0,
    "axes.titlesize": 10.0,
    "axes.labelsize": 9.0,
    "legend.fontsize": 8.0,
    "axes.grid": True,
    "grid.alpha": 0.35,
    "grid.linewidth": 0.6,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "svg.hashsalt": "quadtank-tui",  # the ids of clip paths and glyphs, else random
    "svg.fonttype": "path",  # glyphs as paths: the figure looks the same without the font
    "pdf.fonttype": 42,  # TrueType embedded: text stays text (searchable) in the report
    "path.simplify": True,
    "savefig.dpi": 150,
}

_METADATA: dict[str, dict[str, Any]] = {
    "png": {"Software": CREATOR},
    "svg": {"Date": None, "Creator": CREATOR},
    "pdf": {"Creator": CREATOR, "Producer": CREATOR, "CreationDate": None, "ModDate": None},
}

P = ParamSpec("P")
R = TypeVar("R")


#: rcParams are global: two figures made at once (the E key pressed twice, two
#: workers) would restore each other's settings half-way.  One figure at a time.
_ONE_AT_A_TIME = threading.RLock()


@contextmanager
def context() -> Iterator[None]:
    """The figures' rcParams, for building and for saving (fonts and sizes are read
    when the artists are made, ids and metadata when the file is written)."""
    with _ONE_AT_A_TIME, matplotlib.rc_context(RC):  # type: ignore[arg-type]  # keys checked at run time
        yield


def styled(builder: Callable[P, R]) -> Callable[P, R]:
    """A figure builder run inside `context()`."""
    @functools.wraps(builder)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        with context():
            return builder(*args, **kwargs)
    return run


def new_figure(width: float, height: float) -> Figure:
    """A figure of width x height inches on the Agg canvas: no pyplot, so no display,
    no global figure list, and safe in a worker thread."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def render(fig: Figure, fmt: str) -> bytes:
    """The figure's file in `fmt` (png, svg, pdf): the same bytes for the same data.  A
    figure is drawn once: drawing it again starts its layout from the last one, which
    moves things by a hair (build the figure again for another file)."""
    out = io.BytesIO()
    with context():
        fig.savefig(out, format=fmt, metadata=_METADATA[fmt])
    return out.getvalue()


def save(fig: Figure, path: str | Path) -> Path:
    """Write the figure in the format its suffix names, atomically (a reader sees
    the old file or the whole new one)."""
    return atomic_write_bytes(path, render(fig, figure_format(path)))


def colour(index: int) -> str:
    """The colour of the index-th run (or series) of a figure."""
    return PALETTE[index % len(PALETTE)]
