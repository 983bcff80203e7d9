"""A designed PI/PID loop as a report figure: the closed loop's answer to a unit
reference step, the magnitudes of S = 1/(1 + L) and T = L/(1 + L) with the Ms line,
and the Nyquist curve of L with the circle of radius 1/Ms about -1 (Andersson 4.3:
the curve stays outside it exactly when max |S| <= Ms).

Everything is computed by core/design (the loop, its margins, the simulation with
the dead time exact); this module only draws it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.controller import PID
from quadtank_tui.core.design.evaluate import settled_response
from quadtank_tui.core.design.frequency import Margins, frequency_grid, margins
from quadtank_tui.core.metrics import loop_metrics
from quadtank_tui.files.figures.style import GUIDE_COLOUR, PALETTE, new_figure, styled


@dataclass(frozen=True)
class DesignedLoop:
    """A loop to draw: its name, the model it is closed around, the controller."""

    title: str
    model: DelayTF
    controller: PID


@styled
def design_figure(loops: Sequence[DesignedLoop], title: str = "") -> Figure:
    """One row per loop: reference step, |S| and |T|, Nyquist."""
    fig = new_figure(11.0, 0.6 + 3.0 * len(loops))
    axes = fig.subplots(len(loops), 3, squeeze=False, width_ratios=(1.3, 1.2, 1.0))
    for row, loop in zip(axes, loops):
        L = loop.controller.loop(loop.model)
        m = margins(L)
        _step(row[0], loop, m)
        _bode(row[1], L, m)
        _nyquist(row[2], L, m)
    if title:
        fig.suptitle(title, x=0.01, ha="left")
    return fig


def _step(ax: Axes, loop: DesignedLoop, m: Margins) -> None:
    name = f"{loop.title}\n{loop.controller.kind} {loop.controller.describe()}"
    if not m.stable:
        ax.set_title(f"{name}\nreference step: the closed loop is UNSTABLE", loc="left")
        return
    resp = settled_response(loop.model, loop.controller, m, r=1.0)
    t = np.concatenate([[-1e-9], resp.t])
    y = np.concatenate([[0.0], resp.y])
    lm = loop_metrics(t, y, np.concatenate([[0.0], np.ones_like(resp.y)]))
    settle = "not settled" if lm.settling_time is None else f"{lm.settling_time:.3g} s" \
        if lm.settling_time < 100 else f"{lm.settling_time:.0f} s"
    ax.plot(resp.t, np.ones_like(resp.t), color=GUIDE_COLOUR, linestyle="--", linewidth=1.0, label="r",
            gid="step:r")
    ax.plot(resp.t, resp.y, color=PALETTE[0], linewidth=1.6, label="y", gid="step:y")
    ax.set_title(f"{name}\nunit step: overshoot {lm.overshoot or 0.0:.1f} %, settling {settle}",
                 loc="left")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("y")
    end = float(resp.t[-1])
    if lm.settling_time is not None and lm.settling_time > 0:  # the answer, not the long flat tail
        end = min(end, 4.0 * lm.settling_time)
    ax.set_xlim(0.0, end)
    ax.legend(loc="lower right", frameon=False)


def _bode(ax: Axes, L: DelayTF, m: Margins) -> None:
    w = frequency_grid(L, points=800, decades=2.0)
    Lw = L.freqresp(w)
    S, T = 1.0 / (1.0 + Lw), Lw / (1.0 + Lw)
    ax.loglog(w, np.abs(S), color=PALETTE[1], linewidth=1.5, label="|S|", gid="bode:S")
    ax.loglog(w, np.abs(T), color=PALETTE[2], linewidth=1.5, linestyle="-.", label="|T|", gid="bode:T")
    if np.isfinite(m.Ms):
        ax.axhline(m.Ms, color=GUIDE_COLOUR, linestyle="--", linewidth=1.0, label=f"Ms = {m.Ms:.2f}",
                   gid="bode:Ms")
    ax.set_ylim(1e-3, max(3.0, 2.0 * m.Ms if np.isfinite(m.Ms) else 3.0))
    ax.set_title(f"|S| and |T|\nMs {m.Ms:.2f}, crossover {m.crossover:.3g} rad/s", loc="left")
    ax.set_xlabel("ω (rad/s)")
    ax.legend(loc="best", frameon=False)  # where the curves leave room (data-driven, deterministic)


def _nyquist(ax: Axes, L: DelayTF, m: Margins) -> None:
    w = frequency_grid(L, points=1200, decades=2.0)
    Lw = L.freqresp(w)
    near = np.abs(Lw + 1.0) < 4.0
    shown = np.where(near, Lw, np.nan)  # a gap where the curve leaves the view, no line across it
    ax.plot(shown.real, shown.imag, color=PALETTE[0], linewidth=1.5, label="L(iω)", gid="nyquist:L")
    if np.isfinite(m.Ms) and m.Ms > 0:
        th = np.linspace(0.0, 2 * np.pi, 200)
        ax.plot(-1.0 + np.cos(th) / m.Ms, np.sin(th) / m.Ms, color=PALETTE[1], linewidth=1.3,
                label=f"1/Ms circle ({1 / m.Ms:.2f})", gid="nyquist:circle")
    ax.plot([-1.0], [0.0], "+", color="#000000", markersize=8, gid="nyquist:minus-one")
    ax.set_xlim(-3.0, 1.0)
    ax.set_ylim(-2.5, 1.0)
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(f"Nyquist curve of L\nphase margin {m.phase_margin_deg:.0f}°, gain margin {m.gain_margin:.3g}",
                 loc="left")
    ax.set_xlabel("Re L")
    ax.set_ylabel("Im L")
    ax.legend(loc="upper left", frameon=False)
