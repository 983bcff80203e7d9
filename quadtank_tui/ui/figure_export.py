"""The `E` key of Main, Identify and Design: what the screen shows, as a PNG for a
report, written next to the logs under a name that never replaces an earlier
one, and named in a notification.

The data are taken on the UI thread when the key is pressed (the trends' history,
the fit, the chosen controllers: copies or immutable results); the figure is
built and written in a worker thread, since matplotlib takes a second to import
and a figure another to draw, and the screen must not freeze.  matplotlib is
imported only there (files/figures), never at the TUI's start.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from textual.screen import Screen

    from quadtank_tui.core.delaytf import DelayTF
    from quadtank_tui.core.design.pid_tuning import PIDTuning
    from quadtank_tui.core.identify.experiment import Identification
    from quadtank_tui.core.parameters import Parameters

#: The exports' format: a PNG goes into any word processor (the CLI writes SVG and PDF too).
FORMAT = "png"


def export(screen: Screen[Any], folder: Path, stem: str, build: Callable[[], Figure]) -> None:
    """Build the figure in a worker and write it as folder/stem.png (stem-2.png ...
    if taken); a notification names the file, or says why there is none."""

    def work() -> None:
        from quadtank_tui.files.figures import free_name
        from quadtank_tui.files.figures.style import save

        try:
            figure = build()
            folder.mkdir(parents=True, exist_ok=True)  # a new session's logs/ may not be there yet
            path = save(figure, free_name(folder, stem, FORMAT))
        except (OSError, ValueError) as exc:  # a full disk, a folder gone, nothing to draw
            screen.app.call_from_thread(screen.notify, f"No figure: {exc}", title="Export",
                                        severity="error", markup=False)
            return
        screen.app.call_from_thread(screen.notify, f"Figure saved to {path}", title="Export", markup=False)

    screen.notify(f"Drawing {folder / stem}.{FORMAT} ...", title="Export", timeout=2, markup=False)
    screen.run_worker(work, thread=True, group="figure-export", exit_on_error=False)


def _short(name: str) -> str:
    """A history signal's name as logs and figures call it (ref1 is r1)."""
    return "r" + name[3:] if name.startswith("ref") else name


def trends_builder(history: Mapping[str, np.ndarray], plots: Sequence[str], window: float, offset: float,
                   params: Parameters, physical: bool) -> Callable[[], Figure]:
    """Main's two trends as they are in view: `plots` the upper and lower plot types
    ("y1 ref1"), the last `window` s before `offset` s ago, in the plant's units or
    normalized."""
    t = np.asarray(history["t"], dtype=float)
    end = float(t[-1]) - offset if t.size else 0.0
    keep = (t >= end - window) & (t <= end)
    columns = {_short(n): np.asarray(v, dtype=float)[keep] for n, v in history.items() if n != "t"}
    times = t[keep] - end
    panels = [(f"{where} trend", tuple(_short(n) for n in kind.split())) for where, kind in zip(("upper", "lower"),
                                                                                                  plots)]
    span = f"process time {end - window:.0f} to {end:.0f} s" if end > window else f"process time 0 to {end:.0f} s"

    def build() -> Figure:
        from quadtank_tui.files.figures.runs import Run, runs_figure, scales

        if times.size < 2:
            raise ValueError("no samples in view yet: Run first")
        units = scales("cm" if physical else "norm", params.process_plant())
        return runs_figure([Run("run", times, columns)], (), units, panels=panels, title=span,
                           xlabel="s before the newest sample in view")
    return build


def identification_builder(ident: Identification, params: Parameters) -> Callable[[], Figure]:
    """The fit's validation figure, levels in the plant's unit (cm) as a report wants them."""
    def build() -> Figure:
        from quadtank_tui.files.figures.identification import identification_figure
        from quadtank_tui.files.figures.runs import scales

        return identification_figure(ident, units=scales("cm", params.process_plant()))
    return build


def design_builder(loops: Sequence[tuple[str, DelayTF, PIDTuning, float]], title: str) -> Callable[[], Figure]:
    """Each loop (name, model, controller, the sampling time it runs at) with its
    evaluation, the numbers the screen's table shows."""
    def build() -> Figure:
        from quadtank_tui.files.figures.design import DesignedLoop, design_figure

        return design_figure([DesignedLoop(*loop) for loop in loops], title)
    return build
