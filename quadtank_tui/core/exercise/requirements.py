"""Requirements of an exercise, their figures from sampled signals, their verdicts.

A requirement is one kind (KINDS) with a limit: `max` (the figure must not
exceed it) or `min` (must reach it), and where it applies.  The signal kinds are
measured here on a log's columns (the log's names: t, y1..y4, u1, u2, r1, r2); the model and
design kinds get their figure from the use case (an identification, a design
evaluation) and are only judged here.

>>> import numpy as np
>>> t = np.arange(8.0)
>>> cols = {"t": t, "r1": np.array([0, 0, 1, 1, 1, 1, 1, 1.0]),
...         "y1": np.array([0, 0, 0.5, 1.2, 1.0, 1.0, 1.0, 1.0])}
>>> req = Requirement("overshoot", limit=10.0, loop=1)
>>> figure, detail = signal_figure(req, cols, 1.0)
>>> round(figure, 1), judge(req, figure, detail).met
(20.0, False)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from quadtank_tui.core.exercise.figures import (
    coupling_peak, iae_after, last_step_index, time_at_pump_limit,
)
from quadtank_tui.core.metrics import loop_metrics, rise_time


class RequirementError(ValueError):
    """A requirement that cannot be measured as asked (a column not logged)."""


@dataclass(frozen=True)
class Kind:
    """bound: "max" or "min" (which side of the limit passes); unit of the figure;
    what: the needs of the figure ("step": a loop's step in the log, "log": the
    log alone, "model": an identified model, "design": the controllers in force,
    "attempt": the record's times); text: how the figure is defined (docs, TUI)."""

    bound: str
    unit: str
    what: str
    text: str
    #: the figure can only grow as a run goes on (a max passed is missed for good)
    grows: bool = False


KINDS: dict[str, Kind] = {
    "overshoot": Kind("max", "%", "step", "peak beyond the new reference, % of the step", grows=True),
    "settling_time": Kind("max", "s", "step", "from the step until |r - y| stays within band x step"),
    "rise_time": Kind("max", "s", "step", "10 % to 90 % of the step"),
    "iae": Kind("max", "", "step", "integral of |r - y| dt from the step to the end (normalized x s)", grows=True),
    "steady_state_error": Kind("max", "", "step", "|r - y| at the end of the run (normalized; no step needed)"),
    "coupling": Kind("max", "", "step", "peak |y - y at the step| of the other loop after this loop's step "
                     "(normalized; the design preview's peak in y2)",
                     grows=True),
    "max_level": Kind("max", "", "log", "highest level of the tank over the log (normalized, 1 = 10 V)",
                      grows=True),
    "pump_limit_time": Kind("max", "s", "log", "time either pump spent at 0 or full scale", grows=True),
    "model_zero": Kind("max", "", "model", "relative error of the identified zero nearest the origin "
                       "against the physical one"),
    "model_gain": Kind("max", "", "model", "relative error of the identified static gain against the physical"),
    "ms": Kind("max", "", "design", "max |S| of the sampled loop on the plant's linearization"),
    "phase_margin": Kind("min", "deg", "design", "phase margin of the sampled loop"),
    "gain_margin": Kind("min", "", "design", "gain margin of the sampled loop"),
    "time_limit": Kind("max", "s", "attempt", "wall time from the attempt's start to its end", grows=True),
    #: not written by a teacher: the student's own run holds the exercise's required event (1) or not (0)
    "required_event": Kind("min", "", "attempt", "the required event is in the run (1) or not (0)"),
}
#: The kinds an exercise file may name.
WRITTEN = tuple(k for k in KINDS if k != "required_event")


@dataclass(frozen=True)
class Requirement:
    """One requirement: `kind` (KINDS), `limit` on its bound's side, `loop` (1, 2:
    the step kinds, the design kinds), `band` (settling time, a share of the step),
    `tank` (max_level, 1..4), `element` (model_gain: "11", "12", "21", "22")."""

    kind: str
    limit: float
    loop: int | None = None
    band: float = 0.02
    tank: int | None = None
    element: str | None = None
    line: int = 0

    @property
    def bound(self) -> str:
        return KINDS[self.kind].bound

    @property
    def unit(self) -> str:
        return KINDS[self.kind].unit

    @property
    def name(self) -> str:
        """A short unique-enough name: "overshoot 1", "max_level 4", "model_gain 12"."""
        where = self.loop if self.loop is not None else self.tank if self.tank is not None else self.element
        return self.kind if where is None else f"{self.kind} {where}"

    def limit_text(self) -> str:
        sign = "<=" if self.bound == "max" else ">="
        unit = f" {self.unit}" if self.unit else ""
        return f"{sign} {self.limit:g}{unit}"


@dataclass(frozen=True)
class Verdict:
    """A requirement's figure (None: it could not be measured: no step, not
    settled) and whether it is met; detail says how it came out."""

    requirement: Requirement
    figure: float | None
    met: bool
    detail: str = ""

    @property
    def name(self) -> str:
        return self.requirement.name

    def figure_text(self) -> str:
        if self.figure is None:
            return "-"
        unit = f" {self.requirement.unit}" if self.requirement.unit else ""
        return f"{self.figure:.4g}{unit}"

    def to_dict(self) -> dict[str, object]:
        r = self.requirement
        figure = None if self.figure is None or not math.isfinite(self.figure) else self.figure
        return {"name": r.name, "kind": r.kind, "figure": figure, "limit": r.limit, "bound": r.bound,
                "unit": r.unit, "met": self.met, "detail": self.detail}


def judge(req: Requirement, figure: float | None, detail: str = "") -> Verdict:
    """Met when the figure is on the limit's side (a NaN or missing figure is not)."""
    if figure is None or math.isnan(figure):
        return Verdict(req, figure, False, detail)
    met = figure <= req.limit if req.bound == "max" else figure >= req.limit
    return Verdict(req, float(figure), bool(met), detail)


def live_state(req: Requirement, figure: float | None, finished: bool) -> str:
    """"pending", "met" or "missed" while a run goes on: a figure that only grows
    and is past its max is missed for good; anything else waits for the end."""
    if finished:
        return "met" if judge(req, figure).met else "missed"
    if figure is not None and KINDS[req.kind].grows and req.bound == "max" and figure > req.limit:
        return "missed"
    return "pending"


def _column(cols: Mapping[str, np.ndarray], name: str, req: Requirement) -> np.ndarray:
    if name not in cols:
        raise RequirementError(f"{req.name}: the log has no {name} column (logged: {' '.join(cols)})")
    return np.asarray(cols[name], dtype=float)


def signal_figure(req: Requirement, cols: Mapping[str, np.ndarray], h: float) -> tuple[float | None, str]:
    """The figure of a "step" or "log" requirement on a log's columns, and a detail
    ("no step of ref1", "not settled"); RequirementError for a missing column."""
    kind = KINDS[req.kind]
    if kind.what == "log":
        if req.kind == "max_level":
            y = _column(cols, f"y{req.tank}", req)
            return (float(y.max()) if y.size else None), ""
        return time_at_pump_limit(_column(cols, "u1", req), _column(cols, "u2", req), h), ""
    if kind.what != "step":
        raise RequirementError(f"{req.name}: not a figure of the signals")
    i = req.loop
    t = _column(cols, "t", req) if "t" in cols else np.arange(len(next(iter(cols.values())))) * h
    r, y = _column(cols, f"r{i}", req), _column(cols, f"y{i}", req)
    if req.kind == "steady_state_error":  # with or without a step
        return (abs(float(r[-1] - y[-1])), "") if r.size else (None, "an empty log")
    k = last_step_index(r)
    if k is None:
        return None, f"no step of r{i} in the log"
    if req.kind == "coupling":
        j = 3 - int(i or 1)
        return coupling_peak(_column(cols, f"y{j}", req), k), \
            f"loop {j} after the step of r{i} at {t[k]:g} s"
    m = loop_metrics(t, y, r, band=req.band)
    if req.kind == "overshoot":
        return m.overshoot, ""
    if req.kind == "settling_time":
        return (m.settling_time, "") if m.settling_time is not None else (None, "not settled by the end")
    if req.kind == "rise_time":
        rt = rise_time(t, y, r)
        return (rt, "") if rt is not None else (None, "90 % of the step not reached")
    return iae_after(t, y, r, k), ""
