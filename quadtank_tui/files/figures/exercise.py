"""The class figure of an exercise (`quadtank grade --figures`): every attempt's
response of the stepped loop after its step, overlaid, and the reference
solution's dotted, for the teacher's report."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.figure import Figure

from quadtank_tui.files.figures.style import MODEL_COLOUR, colour, new_figure, save, styled

Curve = tuple[np.ndarray, np.ndarray]  # seconds since the step, normalized level


@styled
def _figure(title: str, curves: Sequence[tuple[str, Curve]], reference: Curve | None) -> Figure:
    fig = new_figure(8.0, 4.5)
    ax = fig.add_subplot(1, 1, 1)
    for i, (label, (t, y)) in enumerate(curves):
        ax.plot(t, y, color=colour(i), linewidth=1.2, label=label)
    if reference is not None:
        ax.plot(reference[0], reference[1], color=MODEL_COLOUR, linestyle=":", linewidth=1.8,
                label="reference solution")
    ax.set_xlabel("time since the step (s)")
    ax.set_ylabel("level, stepped loop (normalized)")
    ax.set_title(title, fontsize="medium")
    ax.grid(True, linewidth=0.3)
    ax.legend(fontsize="small", loc="best")
    return fig


def class_figure(title: str, curves: Sequence[tuple[str, Curve]], reference: Curve | None, path: Path) -> Path:
    """Write the figure to `path` (.png, .svg, .pdf); the same data, the same bytes."""
    return save(_figure(title, curves, reference), path)
