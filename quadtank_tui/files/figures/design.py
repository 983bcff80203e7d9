"""A designed PI/PID loop as a report figure: the closed loop's answer to a unit
reference step, the magnitudes of S = 1/(1 + L) and T = L/(1 + L) with the Ms line,
and the Nyquist curve of L with the circle of radius 1/Ms about -1 (Andersson 4.3:
the curve stays outside it exactly when max |S| <= Ms).

Everything is computed by core/design (the loop, its margins, the simulation with
the dead time exact): for a loop that runs sampled, the sampled loop's curve and
step, and every number in a title is the loop's evaluation, the one the text
prints (`quadtank design`'s Ms and margins); this module only draws it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.design.evaluate import evaluate, settled_response
from quadtank_tui.core.design.evaluation import Evaluation
from quadtank_tui.core.design.frequency import frequency_grid, margins
from quadtank_tui.core.design.simulate import Response
from quadtank_tui.files.figures.style import GUIDE_COLOUR, PALETTE, new_figure, styled


@dataclass(frozen=True)
class DesignedLoop:
    """A loop to draw: its name, the model it is closed around, the controller; `h`
    the sampling time it runs at (0: continuous time) and its evaluation, the one
    the text prints (computed here by core.design.evaluate when not given)."""

    title: str
    model: DelayTF
    controller: PIDTuning
    h: float = 0.0
    evaluation: Evaluation | None = None

    def figures(self) -> Evaluation:
        return self.evaluation or evaluate(self.controller, self.model, h=self.h)


@dataclass(frozen=True)
class _Curves:
    """What one loop's row draws, from the evaluation's own functions."""

    w: np.ndarray
    L: np.ndarray  # L(iw), or L(e^(iwh)) for the sampled loop
    step: Response | None  # the unit reference step (None: unstable)


def _curves(loop: DesignedLoop, ev: Evaluation) -> _Curves:
    c, g, h = loop.controller, loop.model, loop.h
    if h > 0.0:
        from quadtank_tui.core.design.sampled_eval import reference_step, sampled_loop_response

        w, L = sampled_loop_response(c, g, h)
        return _Curves(w, L, reference_step(c, g, h) if ev.stable else None)
    Lc = c.loop(g)
    w = frequency_grid(Lc, points=1200, decades=2.0)
    m = margins(Lc)
    return _Curves(w, Lc.freqresp(w), settled_response(g, c, m, r=1.0) if ev.stable else None)


@styled
def design_figure(loops: Sequence[DesignedLoop], title: str = "") -> Figure:
    """One row per loop: reference step, |S| and |T|, Nyquist; every figure in a
    title is the loop's evaluation (the numbers the text prints)."""
    fig = new_figure(11.0, 0.9 + 3.2 * len(loops))
    axes = fig.subplots(len(loops), 3, squeeze=False, width_ratios=(1.3, 1.2, 1.0))
    for row, loop in zip(axes, loops):
        ev = loop.figures()
        cv = _curves(loop, ev)
        _step(row[0], loop, ev, cv)
        _bode(row[1], ev, cv)
        _nyquist(row[2], ev, cv)
    if title:
        fig.suptitle(title, x=0.01, ha="left")
    return fig


def margin_text(x: float) -> str:
    """A gain margin as a title prints it: 3 figures, no exponent (inf as "inf")."""
    if not np.isfinite(x):
        return "inf"
    return f"{x:.3g}" if abs(x) < 1000 else f"{x:.0f}"


def _step(ax: Axes, loop: DesignedLoop, ev: Evaluation, cv: _Curves) -> None:
    at = f", sampled at {loop.h:g} s" if loop.h > 0 else ""
    name = f"{loop.title}\n{loop.controller.kind} {loop.controller.describe()}{at}"
    if cv.step is None:
        ax.set_title(f"{name}\nreference step: the closed loop is UNSTABLE", loc="left")
        return
    resp = cv.step
    ts = ev.setpoint_settling
    settle = "not settled" if ts is None else f"{ts:.3g} s" if ts < 100 else f"{ts:.0f} s"
    ax.plot(resp.t, np.ones_like(resp.t), color=GUIDE_COLOUR, linestyle="--", linewidth=1.0, label="r",
            gid="step:r")
    ax.plot(resp.t, resp.y, color=PALETTE[0], linewidth=1.6, label="y", gid="step:y")
    ax.set_title(f"{name}\nunit step: overshoot {ev.setpoint_overshoot_pct:.1f} %, settling {settle}",
                 loc="left")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("y")
    end = float(resp.t[-1])
    if ts is not None and ts > 0:  # the answer, not the long flat tail
        end = min(end, 4.0 * ts)
    ax.set_xlim(0.0, end)
    ax.legend(loc="lower right", frameon=False)


def _bode(ax: Axes, ev: Evaluation, cv: _Curves) -> None:
    S, T = 1.0 / (1.0 + cv.L), cv.L / (1.0 + cv.L)
    ax.loglog(cv.w, np.abs(S), color=PALETTE[1], linewidth=1.5, label="|S|", gid="bode:S")
    ax.loglog(cv.w, np.abs(T), color=PALETTE[2], linewidth=1.5, linestyle="-.", label="|T|", gid="bode:T")
    if np.isfinite(ev.Ms):
        ax.axhline(ev.Ms, color=GUIDE_COLOUR, linestyle="--", linewidth=1.0, label=f"Ms = {ev.Ms:.2f}",
                   gid="bode:Ms")
    ax.set_ylim(1e-3, max(3.0, 2.0 * ev.Ms if np.isfinite(ev.Ms) else 3.0))
    ax.set_title(f"|S| and |T|\nMs {ev.Ms:.2f}, crossover {ev.crossover:.3g} rad/s", loc="left")
    ax.set_xlabel("ω (rad/s)")
    ax.legend(loc="best", frameon=False)  # where the curves leave room (data-driven, deterministic)


def _nyquist(ax: Axes, ev: Evaluation, cv: _Curves) -> None:
    Lw = cv.L
    near = np.abs(Lw + 1.0) < 4.0
    shown = np.where(near, Lw, np.nan)  # a gap where the curve leaves the view, no line across it
    ax.plot(shown.real, shown.imag, color=PALETTE[0], linewidth=1.5, label="L", gid="nyquist:L")
    if np.isfinite(ev.Ms) and ev.Ms > 0:
        th = np.linspace(0.0, 2 * np.pi, 200)
        ax.plot(-1.0 + np.cos(th) / ev.Ms, np.sin(th) / ev.Ms, color=PALETTE[1], linewidth=1.3,
                label=f"1/Ms circle ({1 / ev.Ms:.2f})", gid="nyquist:circle")
    ax.plot([-1.0], [0.0], "+", color="#000000", markersize=8, gid="nyquist:minus-one")
    ax.set_xlim(-3.0, 1.0)
    ax.set_ylim(-2.5, 1.0)
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(f"Nyquist curve of L\nphase margin {ev.phase_margin_deg:.0f}°\n"
                 f"gain margin {margin_text(ev.gain_margin)}", loc="left")
    ax.set_xlabel("Re L")
    ax.set_ylabel("Im L")
    # below the axes: inside, it covered the circle about -1
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=2, frameon=False)
