"""The design use case: a decentralized PI/PID pair for the two loops of a 2x2
process, its per-loop candidates, and the preview of a pair on the nonlinear plant.

`quadtank design` (commands/design.py) and the Design screen (from Main and from
Identify) call these functions, so the default they propose and the answer they
give are one:

* the default method is lambda tuning with lambda = max(L, T)/5 per loop
  (core.design.lambda_tuning.default_lambda: at P- a 0.1 step settles in 138 s
  with no overshoot and the pumps clear of their limits);
* when lambda11(0) < 0 (P+: det G(0) has the opposite sign of g11(0) g22(0)) no
  pair of PIs with the diagonal gains' signs is stable, so loop 2 is designed on
  what it sees with loop 1 closed (core.design.mimo), a PI with Ms 1.4;
* a candidate is suggested only when it holds on its own (stable, no pump limit,
  no chatter) and the 2x2 loop with the other loop's controller is stable.

It orchestrates the core; it parses no arguments, prints nothing and draws nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.design.lambda_tuning import first_order
from quadtank_tui.core.design.mimo import Matrix, MimoCheck, design_2x2, lambda11, loop2_with_loop1_closed, slowest_pole
from quadtank_tui.core.design.preview import Preview, horizon, preview, time_constant
from quadtank_tui.core.design.robust import Robustness
from quadtank_tui.core.design.table import MS_VALUES, Candidate, candidates, default_lambdas, suggested
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.plants.base import Plant

METHOD_DEFAULT = "lambda"
MS_DEFAULT = 1.4


def design_pair(G: Matrix, h: float, *, method: str = METHOD_DEFAULT,
                lam: tuple[float | None, float | None] = (None, None), ms: float = MS_DEFAULT) -> MimoCheck:
    """Both loops designed and the 2x2 loop checked, sampled at h s (0: continuous)."""
    return design_2x2(G, method, lam=lam, ms=ms, h=h)


def loop1_must_close(G: Matrix) -> bool:
    """Loop 2 is designed with loop 1 closed: lambda11(0) < 0 (see the module)."""
    return float(lambda11(G, 0.0).real) < 0.0


@dataclass(frozen=True)
class LoopTable:
    """One loop's candidates, on the model they were designed on."""

    loop: int
    model: DelayTF  # what the rows are designed on: G_ii, or g22 with loop 1 closed
    how: str  # "g11", "g22", "g22 with loop 1 closed"
    rows: list[Candidate]
    best: int | None  # the suggested row
    default: int | None  # the row `quadtank design` would give (None: not among the rows)
    T: float  # the first-order T and L the lambdas relate to, s (0 when none)
    L: float
    lambdas: tuple[float, ...]
    h: float


def loop_table(loop: int, model: DelayTF, h: float, *, G: Matrix | None = None, other: PIDTuning | None = None,
               first: PIDTuning | None = None, lambdas: Sequence[float] | None = None,
               ms_values: Sequence[float] = MS_VALUES, u0: float | None = 0.5) -> LoopTable:
    """Loop `loop`'s candidates on `model` (its own element, as typed), sampled at h.

    `G`: the 2x2 model with the typed diagonal (None: no 2x2 check); `other`: the
    other loop's controller the pair is checked with; `first`: loop 1's
    controller, which loop 2 is designed around when loop1_must_close(G).  The
    suggested row is the default design's when it holds, else the least load IAE
    of the rows that hold."""
    how, on = f"g{loop}{loop}", model
    closed = loop == 2 and G is not None and first is not None and loop1_must_close(G)
    if closed:
        assert G is not None and first is not None
        on, how = loop2_with_loop1_closed(G, first), "g22 with loop 1 closed"
    try:
        fo = first_order(on)
        T, L = (0.0 if fo.integrating else fo.T), fo.L
        lams = tuple(lambdas) if lambdas is not None else default_lambdas(fo)
    except DesignError:
        T, L, lams = 0.0, 0.0, tuple(lambdas or ())
    rows = candidates(on, lambdas=lams if lams else None, ms_values=ms_values, h=h, u0=u0)
    if G is not None and other is not None:
        rows = [_with_pair(r, loop, G, other, h) for r in rows]
    if closed:
        want = ("pi-ms", MS_DEFAULT)
    else:
        want = ("lambda", lams[0]) if lams and lambdas is None else ("", 0.0)
    default = next((i for i, r in enumerate(rows) if (r.method, r.parameter) == want), None)
    best = default if default is not None and rows[default].problem is None else suggested(rows)
    return LoopTable(loop, on, how, rows, best, default, T, L, lams, h)


def _with_pair(row: Candidate, loop: int, G: Matrix, other: PIDTuning, h: float) -> Candidate:
    """The row with the 2x2 loop checked: it and the other loop's controller."""
    if row.controller is None or row.evaluation is None or not row.evaluation.stable:
        return row
    c = row.controller.rounded()
    pair = (c, other) if loop == 1 else (other, c)
    try:
        pole = slowest_pole(G, *pair, h)
    except (DesignError, ValueError, ArithmeticError):
        return row
    if pole < 0.0:
        return row
    from dataclasses import replace

    return replace(row, pair=f"the 2x2 loop with loop {3 - loop}'s {other.describe()} is unstable "
                   f"(slowest pole {pole:.3g} 1/s)")


def operating_start(params: Parameters) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Levels (all tanks) and pump volts of the parameters' operating point: the
    steady state through its controlled levels."""
    plant = params.process_plant()
    given = [x if i in plant.controlled else None for i, x in enumerate(params.process_levels())]
    op = plant.steady_inputs(given)
    return tuple(op.x), tuple(op.u)


def tr_of(params: Parameters, keys: Sequence[str]) -> tuple[float, ...]:
    """The anti-windup times Tr (s) of the matrix elements the loops run on."""
    out = []
    for k in keys:
        v = params.get(k)
        out.append(float(getattr(v, "value", v)))
    return tuple(out)


TR_KEYS = ("CONTROLLER ONE.Tr", "CONTROLLER FOUR.Tr")


@dataclass(frozen=True)
class PreviewPlan:
    """What a preview simulates: the same plan gives the same run, TUI or CLI."""

    plant: Plant
    levels: tuple[float, ...]
    inputs: tuple[float, ...]
    pair: tuple[PIDTuning, ...]
    h: float
    model: Sequence[Sequence[DelayTF]] | None
    tr: tuple[float, ...]
    window: float | None = None  # fixed length of each step, s (None: until settled)

    def run(self, progress: Callable[[float], None] | None = None) -> Preview:
        span = horizon(time_constant(self.plant, self.levels, self.inputs, self.model, self.pair, self.h),
                       self.h, self.window)
        return preview(self.plant, self.levels, self.inputs, self.pair, self.h, model=self.model, tr=self.tr,
                       span=span, progress=progress)


def preview_plan(params: Parameters, pair: Sequence[PIDTuning], model: Sequence[Sequence[DelayTF]] | None, h: float,
                 *, start: tuple[Sequence[float], Sequence[float]] | None = None, window: float | None = None,
                 tr_keys: Sequence[str] = TR_KEYS) -> PreviewPlan:
    """The preview of `pair` on the plant in use, from `start` (levels, pump volts;
    None: the parameters' operating point), at sampling time h."""
    if h <= 0.0:
        raise ValueError("the preview on the simulator needs a sampling time > 0")
    levels, inputs = start if start is not None else operating_start(params)
    return PreviewPlan(params.process_plant(), tuple(float(x) for x in levels), tuple(float(u) for u in inputs),
                       tuple(pair), h, model, tr_of(params, tr_keys[:len(pair)]), window)


#: plants in the robustness spread
SPREAD_N = 100


def robustness_of(params: Parameters, plan: PreviewPlan, nominal: Preview, *, n: int = SPREAD_N,
                  seed: int = 0) -> Robustness:
    """The pair of `plan` over `n` plants drawn about the parameters' quadruple tank
    (core.design.robust's stated spread), from the preview's start levels, for as
    long as the nominal steps took to settle and as long again (at most their
    run).  Raises ValueError for a plant the batch path does
    not model (a PLANT section, an effect such as a dead zone, one pump)."""
    from quadtank_tui.core.design.robust import Spread, draw_plants, robustness

    if params.process is not None or any(v for _, v in params.simulation.effects) or len(plan.pair) != 2:
        raise ValueError("the spread runs on the quadruple tank's batch path: not for this plant")
    window = max(min(s.window, 2.0 * s.sim.settling) if s.sim.settling is not None else s.window
                 for s in nominal.steps)
    spread = Spread()
    plants = draw_plants(params.quadtank_constants(), n, spread, seed)
    return robustness(plants, (plan.levels[0], plan.levels[1]), plan.pair, plan.h, window, tr=plan.tr,
                      source=f"the nominal plant and {n - 1} drawn: {spread.describe()}")
