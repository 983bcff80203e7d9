"""An identification as a report figure: per element, the measured and the model
output on the validation part, the residual autocorrelation with its 99 % band,
and the coherence of input and output (Nunes 3.2-3.3's validation plots).

The numbers are the core's (core/identify/validation.py): this module only draws
them.  A model that extracted everything leaves residuals that are white noise,
inside the band at every lag but 0; a simulator without sensor noise leaves only
model error, correlated at every lag however good the fit (the shipped
experiment scripts therefore give the sensors noise).
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from quadtank_tui.core.identify.experiment import Element, Identification
from quadtank_tui.core.identify.validation import WINDOW, autocorrelation, coherence
from quadtank_tui.files.figures.runs import Scale
from quadtank_tui.files.figures.style import (
    BAND_COLOUR, GUIDE_COLOUR, MODEL_COLOUR, SIGNAL_COLOURS, new_figure, styled,
)

#: The coherence is drawn up to this frequency, Hz: where a linear model holds (Nunes 3.2).
COHERENCE_MAX_HZ = 0.1


def element_name(e: Element) -> str:
    return f"G{e.output[1:]}{e.input[1:]}"


@styled
def identification_figure(ident: Identification, title: str = "",
                          units: Mapping[str, Scale] | None = None) -> Figure:
    """One row per element: validation, residual autocorrelation, coherence.
    `units`: per output, normalized -> the unit drawn (runs.scales: levels in cm);
    without, as logged.  The title names the logs by their file names (a path
    in a report's figure says where the student's home folder was)."""
    elements = [ident.elements[key] for key in sorted(ident.elements)]  # G11 G12 G21 G22
    fig = new_figure(11.0, 0.6 + 2.4 * len(elements))
    axes = fig.subplots(len(elements), 3, squeeze=False, width_ratios=(2.2, 1.0, 1.0))
    for row, e in zip(axes, elements):
        _validation(row[0], e, ident.h, (units or {}).get(e.output, Scale(1.0, "normalized")))
        _residuals(row[1], e)
        _coherence(row[2], e, ident.h)
    axes[-1][0].set_xlabel("t (s)")
    axes[-1][1].set_xlabel("lag (samples)")
    axes[-1][2].set_xlabel("f (Hz)")
    fig.suptitle(title or f"{ident.method}: {', '.join(Path(r).name for r in ident.records)}", x=0.01, ha="left")
    return fig


def _validation(ax: Axes, e: Element, h: float, scale: Scale) -> None:
    k = e.split
    t = np.arange(len(e.y)) * h
    part = "validation part" if k else "identification data (no validation part)"
    ax.plot(t[k:], e.y[k:] * scale.factor, color=SIGNAL_COLOURS.get(e.output, "#0072B2"), linewidth=1.8,
            label=f"{e.output} measured", gid=f"{element_name(e)}:measured")
    ax.plot(t[k:], e.ym[k:] * scale.factor, color=MODEL_COLOUR, linewidth=0.9, linestyle="--",
            label=f"{e.output} model", gid=f"{element_name(e)}:model")
    ax.set_title(f"{element_name(e)}: {e.input} → {e.output}, measured and model output\n{part}: fit {e.fit_percent:.1f} %",
                 loc="left")
    ax.set_ylabel(f"{e.output} ({scale.unit})")
    ax.legend(loc="best", frameon=False)


def _residuals(ax: Axes, e: Element) -> None:
    res = e.y[e.split:] - e.ym[e.split:]
    ax.set_title(f"residual autocorrelation\n{100 * e.whiteness:.0f} % of lags in the 99 % band",
                 loc="left")
    if np.ptp(res) == 0:
        ax.text(0.5, 0.5, "residuals all equal", ha="center", transform=ax.transAxes)
        return
    r = autocorrelation(res)
    ax.axhspan(-r.band, r.band, color=BAND_COLOUR, alpha=0.5, linewidth=0, gid=f"{element_name(e)}:band")
    ax.vlines(r.lags, 0.0, r.value, color=SIGNAL_COLOURS.get(e.output, "#0072B2"), linewidth=1.4)
    ax.plot(r.lags, r.value, "o", color=SIGNAL_COLOURS.get(e.output, "#0072B2"), markersize=2.5,
            gid=f"{element_name(e)}:autocorrelation")
    ax.axhline(0.0, color=GUIDE_COLOUR, linewidth=0.6)
    ax.set_ylim(min(-1.05 * r.band, float(r.value.min()) - 0.05), 1.05)


def _coherence(ax: Axes, e: Element, h: float) -> None:
    f, c = coherence(e.u - e.u[0], e.y - e.y[0], h)
    keep = f <= COHERENCE_MAX_HZ
    ax.plot(f[keep], c[keep], color=SIGNAL_COLOURS.get(e.input, "#CC79A7"), linewidth=1.4,
            gid=f"{element_name(e)}:coherence")
    ax.set_ylim(0.0, 1.05)
    ax.set_xlim(0.0, COHERENCE_MAX_HZ)
    ax.set_title(f"coherence {e.input} → {e.output}\nHamming, {min(WINDOW, len(e.u))} points", loc="left")
