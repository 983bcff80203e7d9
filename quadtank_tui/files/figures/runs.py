"""Logged runs as a report figure (`quadtank plot`), and the Main screen's trends.

Each loop gets a panel (y_i with its reference r_i), the upper tanks one, the pump
inputs one.  Several runs are overlaid, each in its own colour, aligned at their
first logged row (LogOn) or at their first reference step, so two controllers'
answers to the same step lie on top of each other.  A panel that holds a loop's
output and reference is annotated with each run's step figures - rise time
(10-90 %), overshoot, settling time (2 % band) and IAE - computed by
core/metrics.py over the whole log, the figures `quadtank log compare` prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from quadtank_tui.core.metrics import MIN_STEP, loop_metrics, rise_time
from quadtank_tui.core.plants.base import Plant
from quadtank_tui.files.figures import FigureError
from quadtank_tui.files.figures.style import (
    LINE_STYLES, OUTPUT_STYLE, REFERENCE_STYLE, SIGNAL_COLOURS, colour, new_figure, styled,
)

UNITS = ("cm", "V", "norm")
ALIGNS = ("logon", "step")
#: The variables `quadtank plot` draws by default (those of them a log has).
DEFAULT_VARS = ("y1", "y2", "r1", "r2")
#: Panels and the variables each may hold, in order.
PANELS = (("loop 1", ("y1", "r1")), ("loop 2", ("y2", "r2")),
          ("upper tanks", ("y3", "y4")), ("pump inputs", ("u1", "u2")))


@dataclass(frozen=True)
class Run:
    """One run: its name in the legend, times (s, already aligned) and columns
    (normalized, as logged: y, u in [0, 1], r the references)."""

    label: str
    t: np.ndarray
    columns: Mapping[str, np.ndarray]


@dataclass(frozen=True)
class Scale:
    """A signal in the unit shown: value = normalized x factor."""

    factor: float
    unit: str


def scales(units: str, plant: Plant) -> dict[str, Scale]:
    """Per variable, normalized -> `units`: "norm" as logged (1 = 10 V), "V" the
    sensor and pump volts, "cm" the levels in the plant's length unit (cm for the
    quadruple tank, through its sensor gain) and the pumps in V."""
    if units not in UNITS:
        raise FigureError(f"--units must be one of {', '.join(UNITS)}, got {units!r}")
    out: dict[str, Scale] = {}
    for n in (1, 2, 3, 4):
        state = plant.states[n - 1] if n - 1 < len(plant.states) else None
        for name in (f"y{n}", f"r{n}"):
            if units == "norm":
                out[name] = Scale(1.0, "normalized")
            elif units == "V" or state is None:
                out[name] = Scale(10.0, "V")
            else:
                out[name] = Scale(state.full_scale, state.unit)
    for n in (1, 2):
        pump = plant.inputs[n - 1] if n - 1 < len(plant.inputs) else None
        full = pump.full_scale if pump is not None and units != "V" else 10.0
        out[f"u{n}"] = Scale(1.0, "normalized") if units == "norm" else Scale(full, "V")
    return out


def align(run: Run, how: str, where: str) -> Run:
    """The run with t = 0 at its first row (`logon`) or at its first reference step
    (`step`: of r1, else r2: the step a run was logged for, before any later one);
    `where` names it in an error."""
    if how == "logon":
        return Run(run.label, run.t - run.t[0], run.columns)
    if how != "step":
        raise FigureError(f"--align must be one of {', '.join(ALIGNS)}, got {how!r}")
    refs = [r for r in ("r1", "r2") if r in run.columns]
    if not refs:
        raise FigureError(f"{where}: --align step needs r1 or r2 logged (the steps are found there)")
    for r in refs:
        jumps = np.nonzero(np.abs(np.diff(run.columns[r])) > MIN_STEP)[0]
        if jumps.size:
            return Run(run.label, run.t - run.t[int(jumps[0]) + 1], run.columns)
    raise FigureError(f"{where}: no reference step in {' or '.join(refs)} (a change of more than 0.01) "
                      "to align at; --align logon aligns at the first row")


def _seconds(x: float | None) -> str:
    if x is None:
        return "-"
    return f"{x:.0f} s" if abs(x) >= 100 else f"{x:.3g} s"


def step_text(run: Run, loop: int, scale: Scale) -> str | None:
    """The run's step figures of loop `loop` (2 % band) for the annotation, or None without a step
    (or without y_i and r_i)."""
    y, r = f"y{loop}", f"r{loop}"
    if y not in run.columns or r not in run.columns:
        return None
    m = loop_metrics(run.t, run.columns[y], run.columns[r])
    if m.step is None:
        return None
    rise = rise_time(run.t, run.columns[y], run.columns[r])
    settling = "not settled" if m.settling_time is None else _seconds(m.settling_time)
    unit = "" if scale.unit == "normalized" else f" {scale.unit}·s"
    return (f"{run.label} y{loop}: rise {'not reached' if rise is None else _seconds(rise)}, "
            f"overshoot {m.overshoot or 0.0:.1f} %, settling {settling}, IAE {m.iae * scale.factor:.3g}{unit}")


def panels_for(names: Sequence[str]) -> list[tuple[str, tuple[str, ...]]]:
    """The panels the chosen variables fall into, each with its chosen variables."""
    out = []
    for title, members in PANELS:
        chosen = tuple(n for n in members if n in names)
        if chosen:
            out.append((title, chosen))
    return out


def _quantity(names: Sequence[str], scale: Scale) -> str:
    what = "pump input" if all(n.startswith("u") for n in names) else "level"
    if any(n.startswith("u") for n in names) and what == "level":
        what = "level, pump input"
    return f"{what} ({scale.unit})"


@styled
def runs_figure(runs: Sequence[Run], names: Sequence[str], units: Mapping[str, Scale], *,
                xlabel: str, title: str = "", panels: Sequence[tuple[str, tuple[str, ...]]] | None = None,
                metrics: bool = True) -> Figure:
    """One panel per group of `names` (or the `panels` given), every run overlaid.

    One run: each variable in its own colour (SIGNAL_COLOURS).  Several: one colour
    per run, the variables of a panel told apart by line style.  References are
    dashed and under the outputs."""
    if not runs:
        raise FigureError("no run to draw")
    groups = list(panels) if panels is not None else panels_for(names)
    if not groups:
        raise FigureError("no variable to draw")
    fig = new_figure(8.0, 0.8 + 2.3 * len(groups))
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
    several = len(runs) > 1
    for ax, (panel, members) in zip(axes, groups):
        _panel(ax, runs, members, units, several)
        ax.set_ylabel(_quantity(members, units[members[0]]))
        notes = []
        for loop in (1, 2):
            if metrics and f"y{loop}" in members and f"r{loop}" in members:
                notes += [t for t in (step_text(r, loop, units[f"y{loop}"]) for r in runs) if t]
        # Above the data, full width: the panel's name, then each run's step figures.
        ax.set_title("\n".join([f"{panel}: {', '.join(members)}"] + notes), loc="left")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    axes[-1].set_xlabel(xlabel)
    if title:
        fig.suptitle(title, x=0.01, ha="left")
    return fig


def _panel(ax: Axes, runs: Sequence[Run], members: Sequence[str], units: Mapping[str, Scale],
           several: bool) -> None:
    outputs = [n for n in members if not n.startswith("r")]
    for k, run in enumerate(runs):
        prefix = f"{run.label} " if several else ""
        for j, name in enumerate(members):
            if name not in run.columns:
                continue
            values = np.asarray(run.columns[name], dtype=float) * units[name].factor
            c = colour(k) if several else SIGNAL_COLOURS.get(name, colour(j))
            if name.startswith("r"):  # held between samples, as the loop holds them
                ax.plot(run.t, values, color=c, label=f"{prefix}{name}", gid=f"{run.label}:{name}",
                        drawstyle="steps-post", **REFERENCE_STYLE)
            else:
                style = LINE_STYLES[outputs.index(name) % len(LINE_STYLES)] if several else "-"
                ax.plot(run.t, values, color=c, linestyle=style, label=f"{prefix}{name}",
                        gid=f"{run.label}:{name}", drawstyle="steps-post" if name.startswith("u") else "default",
                        **OUTPUT_STYLE)
    lo = min(float(r.t[0]) for r in runs)
    hi = max(float(r.t[-1]) for r in runs)
    if math.isfinite(lo) and hi > lo:
        ax.set_xlim(lo, hi)
