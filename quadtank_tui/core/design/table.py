"""A comparison table of candidate controllers in the style of Andersson's 4.4:
three lambdas, PI_opt and this program's PID at three Ms values, each evaluated
on one model (the "simulation model", by default the design model).

A candidate that cannot be designed on the model (e.g. lambda on a model with a
right-half-plane pole) is kept as a row with its reason, so the table always says
why a cell is empty.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Callable, Sequence

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.design.evaluate import evaluate
from quadtank_tui.core.design.evaluation import Evaluation
from quadtank_tui.core.design.lambda_tuning import FirstOrder, default_lambda, first_order, lambda_pi
from quadtank_tui.core.design.optimize import pi_ms, pid_ms
from quadtank_tui.core.design.sampled import sample
from quadtank_tui.core.design.sampled_eval import LimitCheck, evaluate_sampled

MS_VALUES = (1.6, 1.4, 1.2)


@dataclass(frozen=True)
class Candidate:
    method: str  # "lambda", "pi-ms", "pid-ms"
    parameter: float  # lambda (s) or Ms
    controller: PIDTuning | None
    evaluation: Evaluation | None
    error: str | None = None
    #: the sampled loop's steps with the pumps limited (h > 0 only)
    limits: LimitCheck | None = None
    #: the 2x2 loop with the other loop's controller, when it is unstable: why (None: stable or unchecked)
    pair: str | None = None

    @property
    def problem(self) -> str | None:
        """Why this row must not be suggested: no design, unstable, the limit
        check's verdict (saturates, chatters, never settles), or the 2x2 loop with
        the other loop's controller unstable."""
        if self.controller is None or self.evaluation is None:
            return self.error or "no controller"
        if not self.evaluation.stable:
            return "unstable"
        if self.limits is not None and self.limits.problem is not None:
            return self.limits.problem
        return self.pair

    @property
    def label(self) -> str:
        name = {"lambda": "Lambda", "pi-ms": "PI Ms", "pid-ms": "PID Ms"}[self.method]
        return f"{name} {self.parameter:.3g}" if self.method != "lambda" else f"{name} \u03bb={self.parameter:.3g}"


def default_lambdas(fo: FirstOrder) -> tuple[float, ...]:
    """The default lambda (lambda_tuning.default_lambda, the one `quadtank design`
    uses) first, then slower ones: T/5, T/2, T without a dead time; an integrating
    model 2, 4 and 8 times its delay (Andersson's process 4 used 3, 5 and 9 L,
    process 2 2.3-6.8 L)."""
    lam = default_lambda(fo)
    if fo.integrating:
        return (lam, 2.0 * lam, 4.0 * lam)
    return (lam, 2.5 * lam, 5.0 * lam)


def candidates(g: DelayTF, *, evaluate_on: DelayTF | None = None,
               lambdas: Sequence[float] | None = None,
               ms_values: Sequence[float] = MS_VALUES, h: float = 0.0,
               u0: float | None = 0.5) -> list[Candidate]:
    """Design and evaluate every candidate (9 with the defaults).

    h = 0: Andersson's continuous-time designs and figures.  h > 0: each design is
    for the loop sampled at h (core.design.optimize, lambda_tuning) and its figures
    are the sampled loop's, with the limit check around the operating input u0
    (normalized, 0..1; None: no check)."""
    target = evaluate_on or g
    rows: list[Candidate] = []
    sampled = sample(target, h) if h > 0.0 else None

    def add(method: str, par: float, make: Callable[[], PIDTuning]) -> None:
        try:
            c = make()
            if sampled is None:
                rows.append(Candidate(method, par, c, evaluate(c, target, setpoint=False)))
                return
            se = evaluate_sampled(c, target, h, u0=u0, setpoint=False, model=sampled)
            rows.append(Candidate(method, par, c, se.evaluation, limits=se.limits))
        except DesignError as exc:
            rows.append(Candidate(method, par, None, None, str(exc)))

    try:
        fo = first_order(g)
        lams = tuple(lambdas) if lambdas is not None else default_lambdas(fo)
        for lam in lams:
            add("lambda", lam, partial(lambda_pi, fo, lam, h))
    except DesignError as exc:
        rows.append(Candidate("lambda", 0.0, None, None, str(exc)))
    for ms in ms_values:
        add("pi-ms", ms, partial(pi_ms, g, ms, h=h))
    for ms in ms_values:
        add("pid-ms", ms, partial(pid_ms, g, ms, h=h))
    return rows


def suggested(rows: Sequence[Candidate]) -> int | None:
    """Index of the row to suggest: the smallest load IAE among the stable rows with
    no problem (never one that saturates, chatters or does not settle); None if
    every row has one."""
    ok = [i for i, r in enumerate(rows) if r.problem is None and r.evaluation is not None]
    return min(ok, key=lambda i: rows[i].evaluation.IAE) if ok else None  # type: ignore[union-attr]


def format_table(rows: Sequence[Candidate]) -> str:
    """Plain-text table (CLI, benchmark, closing notes)."""
    widths = (16, 9, 9, 7, 9, 7, 6, 6, 7, 7, 6)
    names = ("candidate", "Kc", "Ti", "Td", "IAE", "Emax", "u_os", "phi_m", "Lm", "Am", "Ms")

    def line(cells: Sequence[str]) -> str:
        return cells[0].ljust(widths[0]) + " ".join(c.rjust(w) for c, w in zip(cells[1:], widths[1:]))

    out = [line(names)]
    for r in rows:
        if r.controller is None or r.evaluation is None:
            out.append(f"{r.label:<16}  {r.error}")
            continue
        c, e = r.controller, r.evaluation
        head = [r.label, f"{c.Kc:.4g}", f"{c.Ti:.4g}", f"{c.Td:.3g}"]
        if not e.stable:
            out.append(line(head) + "  unstable on this model")
            continue
        out.append(line(head + [f"{e.IAE:.4g}", f"{e.Emax:.3g}", f"{e.u_overshoot:.2f}",
                                f"{e.phase_margin_deg:.0f}", f"{e.delay_margin:.3g}",
                                f"{e.gain_margin:.3g}", f"{e.Ms:.2f}"])
                   + (f"  {r.problem}" if r.limits is not None and r.problem else ""))
    best = suggested(rows)
    if any(r.limits is not None for r in rows):
        out.append("suggested: " + (rows[best].label if best is not None else
                                    "none (every row saturates, chatters or does not settle)"))
    return "\n".join(out)
