"""The Design screen (B3): a PI/PID for each loop from a model, compared in a
table in the style of Andersson's section 4.4, checked on the 2x2 process, and
applied to the running controller matrix.

The models start as the physical linearization of the current setting (g11 and
g22 at its operating levels), or as an identified model's G11 and G22 when the
Identify screen opens this one, and can be typed over (`1.66*exp(-2.4*s)/(1.07*s+1)^3`);
they are shown as gain, dead time and time constants (ui/model_text.py).  The
lambdas and Ms values of the candidates are typed too, per loop (`T/4 T/2 T`,
`1.6 1.4 1.2`: ui/design_inputs.py).  Designing and evaluating the candidates
takes a second or two, so it runs in a worker; the process keeps running
underneath.  Below 110 columns the table takes the width (`v` swaps in the
plots).  Esc goes back to the screen that opened this one, and the footer names
it.  Nothing reaches the engine until Apply (A): then one SetParams, bumpless
like any parameter change, and a notification of what changed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.geometry import Size
from textual.widgets import Input, Label, Static

from quadtank_tui.core.delaytf import DelayTF, ModelError
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.design_inputs import InputError, format_values, parse_lambdas, parse_ms
from quadtank_tui.ui.model_text import model_text
from quadtank_tui.ui.screens.design_plots import (DesignPlots, draw_load_step, draw_nyquist,
                                                  draw_reference_steps, draw_sensitivity)
from quadtank_tui.ui.screens.sending import CommandSender
from quadtank_tui.ui.widgets.candidates_table import CandidatesTable, label
from quadtank_tui.ui.widgets.key_footer import KeyFooter
from quadtank_tui.ui.widgets.plot_view import PlotView

if TYPE_CHECKING:  # the design core loads when the screen first computes (start-up time)
    from quadtank_tui.core.design.mimo import Matrix, MimoCheck
    from quadtank_tui.core.design.simulate import Response
    from quadtank_tui.app.design import LoopTable
    from quadtank_tui.core.design.table import Candidate

HELP = "Tab: models, λ, Ms; Enter designs · Enter on a row: choose it for the loop"
#: Below this width the table takes the screen's width and `v` swaps it with the plots.
NARROW = 110
#: Fewer rows: the Nyquist plot, too small to draw at its aspect, is a few rows of
#: its figures (design.tcss's -short), and the step plot gets the rows.
SHORT = 29
MS_DEFAULT = "1.6 1.4 1.2"


@dataclass
class LoopState:
    """What the screen holds for one loop (the UI keeps no control logic: the
    numbers come from core.design)."""

    text: str = ""
    model: DelayTF | None = None
    #: what the rows are designed on (app.design.loop_table): the model, or g22 with loop 1 closed
    design_model: DelayTF | None = None
    how: str = ""
    rows: list[Candidate] = field(default_factory=list)
    chosen: PIDTuning | None = None
    chosen_label: str = ""
    #: The lambdas typed ("": the method's defaults for the model) and the Ms values.
    lambdas: str = ""
    ms: str = MS_DEFAULT
    #: The first-order T and L (s) the lambdas were taken relative to; the lambdas used.
    T: float = 0.0
    L: float = 0.0
    used: tuple[float, ...] = ()
    #: The sampling time the rows were designed and evaluated at (s), the suggested row.
    h: float = 0.0
    best: int | None = None
    #: Which table request is the newest (an older worker's rows are dropped).
    request: int = 0


class DesignScreen(CommandSender):
    """Models per loop, the candidates table, Nyquist and load-step plots, the
    2x2 check, Apply."""

    AUTO_FOCUS = "#design-table"  # letter keys act; Tab or a click reaches a model

    BINDINGS = [
        # One of the two shows, the screen that opened this one (check_action): Esc
        # goes where the footer says.
        Binding("escape", "back('Main')", "Main"),
        Binding("escape", "back('Identify')", "Identify"),
        Binding("l", "switch_loop", "Loop 1/2"),
        Binding("2", "design_2x2", "2x2 design"),
        Binding("x", "check", "2x2 check"),
        Binding("A", "apply", "Apply"),
        Binding("p", "physical", "Physical models", show=False),
        Binding("v", "plots", "Plots"),  # only below NARROW columns (check_action)
        Binding("b", "bode", "Bode/steps"),
        Binding("E", "export_figure", "Export figure", show=False,
                tooltip="The chosen controllers' step, |S| |T| and Nyquist plots as a PNG in the logs folder"),
    ]

    def __init__(self, engine: EngineHandle,
                 identified: Sequence[Sequence[DelayTF | None]] | None = None,
                 identified_name: str = "the identified model") -> None:
        """`identified`: [[G11, G12], [G21, G22]] of an identified model (None for a
        missing element) to start from instead of the physical linearization."""
        super().__init__()
        self.engine = engine
        self.snap: Snapshot = engine.snapshot()
        self.loops = {1: LoopState(), 2: LoopState()}
        self.loop = 1
        self.identified = identified
        self.identified_name = identified_name
        self.G: Matrix | None = None  # the 2x2 DelayTF matrix of the 2x2 design and check
        self.source = "the physical linearization"  # what G is, for messages
        self.frequency_view = False  # b: |S| |T| and the load step instead of Nyquist and the steps
        self._plots: DesignPlots | None = None
        self._plot_args: tuple[DelayTF, PIDTuning, float | None] | None = None  # the candidate on show
        self._told_best = False  # a new table's status named its suggested row

    def compose(self) -> ComposeResult:
        yield Static(id="design-status")
        with Vertical(id="design-models"):
            for i in (1, 2):
                with Horizontal(classes="design-row"):
                    yield Label(f"Loop {i}  y{i}←u{i}", classes="model-label")
                    yield Input(id=f"model-{i}", classes="model", compact=True)
            with Horizontal(classes="design-row"):
                yield Label("λ", id="lambdas-label", classes="model-label")
                yield Input(id="lambdas", classes="tuning", compact=True,
                            tooltip="lambdas in s, or multiples of T or L: T/4 T/2 T, 2L 4L")
                yield Label("Ms", id="ms-label", classes="model-label")
                yield Input(id="ms", classes="tuning", compact=True, tooltip="Ms values, > 1: 1.6 1.4 1.2")
                yield Label(id="tuning-note")
        with Horizontal(id="design-body"):
            with Vertical(id="design-left"):
                table = CandidatesTable(id="design-table")
                table.border_title = "Candidates"
                yield table
                yield Static(id="design-chosen")
                yield Static(id="design-mimo")
            with Vertical(id="design-right"):
                yield PlotView(id="nyquist")
                yield PlotView(id="response")
        yield Static(HELP, id="design-help")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.query_one("#nyquist", PlotView).border_title = "Nyquist L(iω)"
        self.query_one("#response", PlotView).border_title = "Reference steps"
        for plot in self.query(PlotView):  # a new size: the ticks laid out again
            plot.relayout = self._redraw_plots
        self._show_tuning()
        if self.identified is not None:
            self.action_identified()
        else:
            self.action_physical()

    # --- navigation ------------------------------------------------------------------

    @property
    def opener(self) -> str:
        """The screen Esc goes back to: the one under this one (Identify opens it
        with `d` on a fitted model, Main with `d`)."""
        stack = self.app.screen_stack
        below = stack[stack.index(self) - 1] if self in stack and stack.index(self) > 0 else None
        return "Identify" if type(below).__name__ == "IdentifyScreen" else "Main"

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "back":
            return parameters == (self.opener,)
        if action == "plots":
            return self.has_class("-narrow")
        return True

    def action_back(self, to: str) -> None:
        self.app.pop_screen()

    def pack(self, size: Size) -> None:
        super().pack(size)
        # Below SHORT rows the Nyquist plot cannot be drawn at its aspect: it says its
        # figures in a few rows and the step plot takes the rest (issue 43).
        self.set_class(size.height < SHORT, "-short")
        narrow = size.width < NARROW
        if narrow != self.has_class("-narrow"):
            self.set_class(narrow, "-narrow")
            self.refresh_bindings()
            self._show_tuning()

    def action_plots(self) -> None:
        """Below NARROW columns: the plots in the table's place, or back."""
        self.toggle_class("-plots")

    # --- models ----------------------------------------------------------------------

    def action_physical(self) -> None:
        """Both loops' models from the physical linearization of the current setting."""
        from quadtank_tui.core.design.pid_tuning import DesignError
        from quadtank_tui.core.design.mimo import model_in_use
        from quadtank_tui.core.plants.common import PlantError

        p = self.engine.snapshot().params
        self.source = "the physical linearization"
        try:
            self.G = model_in_use(p)  # the plant in use, not always the quadruple tank
        except (PlantError, DesignError) as exc:
            self.G = None
            self._status(f"no physical linearization: {exc}")
            return
        self._set_models(self.G[0][0], self.G[1][1])
        self._status("models: the physical linearization at the setting's operating levels")

    def action_identified(self) -> None:
        """Loop i's model is the identified G_ii; the 2x2 check uses all four
        elements when the model has them."""
        assert self.identified is not None
        (g11, g12), (g21, g22) = self.identified
        self.source = self.identified_name
        if g11 is not None and g12 is not None and g21 is not None and g22 is not None:
            self.G = ((g11, g12), (g21, g22))
        else:
            self.G = None
        full = self.G is not None
        self._set_models(g11, g22)
        self._status(f"models: G11 and G22 of {self.identified_name}"
                     + ("" if full else " (G12 or G21 missing: no 2x2 check)"))

    def _set_models(self, g11: DelayTF | None, g22: DelayTF | None) -> None:
        for i, g in ((1, g11), (2, g22)):
            self._set_model(i, g, "" if g is None else model_text(g))
        self._show_tuning()
        self._start_design()

    def typed_matrix(self) -> Matrix | None:
        """The 2x2 model with the loops' models as shown (typed over or not);
        None without a full 2x2 model."""
        g1, g2 = self.loops[1].model, self.loops[2].model
        if self.G is None or g1 is None or g2 is None:
            return None
        return ((g1, self.G[0][1]), (self.G[1][0], g2))

    def _start_design(self) -> None:
        """The default pair first (app.design.design_pair: what `quadtank design`
        gives), chosen for both loops, then the table of the loop shown, checked
        with the other loop's choice."""
        G = self.typed_matrix()
        if G is None:
            self.design_loop(self.loop)
            return
        self._status(f"designing both loops on {self.source} ...")
        self._compute_2x2(G, default=True)

    def _set_model(self, loop: int, g: DelayTF | None, text: str) -> None:
        """Loop `loop` on model `g` (nothing chosen yet); its lambdas and Ms stay typed."""
        was = self.loops[loop]
        self.loops[loop] = LoopState(text=text, model=g, lambdas=was.lambdas, ms=was.ms, request=was.request)
        self.query_one(f"#model-{loop}", Input).value = text

    @on(Input.Submitted, ".model")
    def model_typed(self, event: Input.Submitted) -> None:
        from quadtank_tui.core.design.expr import parse_model

        loop = 1 if event.input.id == "model-1" else 2
        state = self.loops[loop]
        if event.value == state.text and state.model is not None:  # as shown: the exact model
            g = state.model
        else:
            try:
                g = parse_model(event.value)
            except ModelError as exc:
                # The message quotes what was typed: plain text, never markup.
                self.notify(str(exc), title=f"Loop {loop} model", severity="error", timeout=8, markup=False)
                return
            self._set_model(loop, g, event.value)
        self.loop = loop
        self._show_tuning()
        self._start_design()
        self._show_chosen()

    @on(Input.Submitted, ".tuning")
    def tuning_typed(self, event: Input.Submitted) -> None:
        """New lambdas or Ms values for the loop shown: its table anew (checked in
        the worker, against the model's T and L; a bad entry changes nothing)."""
        state = self.loops[self.loop]
        if event.input.id == "ms":
            self.design_loop(self.loop, ms=event.value)
            return
        text = event.value.strip()
        if not state.lambdas and text == format_values(state.used):
            text = ""  # the defaults as shown stay the defaults (they follow the model)
        self.design_loop(self.loop, lambdas=text)

    def _show_tuning(self) -> None:
        """The lambda and Ms boxes and the note on T and L, for the loop shown."""
        state = self.loops[self.loop]
        self.query_one("#lambdas-label", Label).update(f"Loop {self.loop}  λ")
        for box, text in (("#lambdas", state.lambdas or format_values(state.used)), ("#ms", state.ms)):
            entry = self.query_one(box, Input)
            if not entry.has_focus:  # never under the user's typing
                entry.value = text
        # The model's T and L the multiples are of; what a λ may be when there is room
        what = "" if self.has_class("-narrow") else "λ in s or as T/4, 2L "
        note = f"{what}(T {state.T:.3g} s, L {state.L:.3g} s)" if state.used else what.strip()
        self.query_one("#tuning-note", Label).update(note)

    # --- the table -------------------------------------------------------------------

    def design_loop(self, loop: int, *, lambdas: str | None = None, ms: str | None = None) -> None:
        """Design loop `loop`'s candidates in a worker; `lambdas` / `ms`: new entries
        (None: those in force).  The table shown stays until the new one is ready."""
        state = self.loops[loop]
        state.request += 1
        if state.model is None:
            self._status(f"loop {loop}: no model; type one")
            return
        self._status(f"designing loop {loop} ...")
        self._compute_table(loop, state.model, state.request, state.lambdas if lambdas is None else lambdas,
                            state.ms if ms is None else ms, self.typed_matrix(), self.loops[3 - loop].chosen,
                            self.loops[1].chosen)

    @work(thread=True, exclusive=True, group="table")
    def _compute_table(self, loop: int, model: DelayTF | None, request: int, lambdas: str, ms: str,
                       G: Matrix | None, other: PIDTuning | None, first: PIDTuning | None) -> None:
        """app.design.loop_table (the rows on what the loop sees, each checked in the
        2x2 loop with the other loop's choice), after the typed entries are parsed
        against the design model's T and L."""
        from quadtank_tui.app.design import loop1_must_close, loop_table
        from quadtank_tui.core.design.pid_tuning import DesignError
        from quadtank_tui.core.design.lambda_tuning import first_order
        from quadtank_tui.core.design.mimo import loop2_with_loop1_closed

        if model is None:
            return
        on = model
        if loop == 2 and G is not None and first is not None and loop1_must_close(G):
            on = loop2_with_loop1_closed(G, first)
        try:
            fo = first_order(on)
            T, L = (0.0 if fo.integrating else fo.T), fo.L
        except DesignError:  # no lambda rows (the table says why); the lambdas are not used
            T, L = 0.0, 0.0
        try:
            ms_values = parse_ms(ms)
            lams = parse_lambdas(lambdas, T, L) if lambdas else None
        except InputError as exc:
            self.app.call_from_thread(self._refused, loop, request, str(exc))
            return
        snap = self.engine.snapshot()  # the loop as it runs: its sampling time, its pump's input
        h = snap.params.tsamp
        try:
            table = loop_table(loop, model, h, G=G, other=other, first=first, lambdas=lams, ms_values=ms_values,
                               u0=snap.u[loop - 1] if snap.state == "Run" else 0.5)
        except (ValueError, DesignError) as exc:  # a model the evaluation cannot simulate: one line, no crash
            self.app.call_from_thread(self._status, f"loop {loop}: {exc}", error=True)
            return
        self.app.call_from_thread(self._show_table, loop, request, table, (lambdas, ms))

    def _refused(self, loop: int, request: int, why: str) -> None:
        """A bad lambda or Ms entry: said, and the table and the entries in force kept."""
        if request == self.loops[loop].request:
            self._status(f"loop {loop}: {why}; the table is as it was", error=True)
            self.notify(why, title=f"Loop {loop}", severity="error", timeout=8, markup=False)

    def _show_table(self, loop: int, request: int, table: LoopTable, tuning: tuple[str, str]) -> None:
        state = self.loops[loop]
        if request != state.request:
            return  # a newer model or entry came meanwhile
        rows, best = table.rows, table.best
        state.rows, state.best, state.h = rows, best, table.h
        state.design_model, state.how = table.model, table.how
        state.lambdas, state.ms = tuning
        state.T, state.L, state.used = table.T, table.L, table.lambdas
        if loop == self.loop:
            self._fill_table(to_best=True)
            self._show_tuning()
        shown = model_text(state.model) if state.model is not None else ""
        on = f" ({table.how})" if table.how.endswith("closed") else ""
        best_text = (f"; suggested {label(rows[best])}" + (" (the default design)" if best == table.default else "")
                     if best is not None else "; none suggested (each fails the check)")
        # the table's highlight of its suggested row comes next: this line stays
        self._told_best = loop == self.loop and best is not None
        self._status(f"loop {loop}: {len(rows)} candidates on {shown}{on}{best_text}")

    def _fill_table(self, *, to_best: bool = False) -> None:
        """The loop's rows; `to_best`: a new table, the cursor on its suggested row."""
        state = self.loops[self.loop]
        table = self.query_one(CandidatesTable)
        sampled = f", sampled at {state.h:g} s" if state.h > 0 else ", continuous time"
        table.border_title = f"Candidates, loop {self.loop}{sampled}"
        table.show(state.rows, best=state.best, to_best=to_best)

    def action_switch_loop(self) -> None:
        self.loop = 3 - self.loop
        state = self.loops[self.loop]
        self._show_tuning()
        if state.rows:
            self._fill_table()
        else:
            self.design_loop(self.loop)
        self._show_chosen()

    def _row(self, key: str | None) -> Candidate | None:
        """The candidate of a row key (None: no row, e.g. a table emptied under the cursor)."""
        rows = self.loops[self.loop].rows
        if key is None or not key.isdigit() or int(key) >= len(rows):
            return None
        return rows[int(key)]

    @on(CandidatesTable.RowHighlighted, "#design-table")
    def row_highlighted(self, event: CandidatesTable.RowHighlighted) -> None:
        row = self._row(_key(event.row_key))
        state = self.loops[self.loop]
        model = state.design_model or state.model
        if row is not None and row.error:
            self._status(f"{label(row)}: {row.error}")
        elif row is not None and row.problem is not None:  # the check column's word, in full
            self._status(f"{label(row)}: {row.problem}")
        elif row is not None and event.cursor_row == state.best:
            if self._told_best:  # the new table's status says it already
                self._told_best = False
            else:
                self._status(f"{label(row)} suggested: least load IAE of the rows that hold")
        if row is not None and row.controller is not None and model is not None:
            self._plot_args = (model, row.controller, row.parameter if row.method != "lambda" else None)
            self._compute_plots(*self._plot_args)

    @on(CandidatesTable.RowSelected, "#design-table")
    def row_selected(self, event: CandidatesTable.RowSelected) -> None:
        row = self._row(_key(event.row_key))
        if row is None or row.controller is None:
            self.notify("this candidate has no controller", severity="warning")
            return
        state = self.loops[self.loop]
        state.chosen, state.chosen_label = row.controller.rounded(), label(row)
        other = self.loops[3 - self.loop]
        other.rows, other.request = [], other.request + 1  # its rows' 2x2 check (and P+'s loop 2 model) changed
        if row.pair is not None:
            self.notify(row.pair, title=f"Loop {self.loop}", severity="warning", markup=False)
        self._show_chosen()

    def _show_chosen(self) -> None:
        lines = []
        for i in (1, 2):
            s = self.loops[i]
            what = f"{s.chosen.describe()}  ({s.chosen_label})" if s.chosen else "[dim]none chosen[/]"
            mark = "▸" if i == self.loop else " "
            lines.append(f"{mark} loop {i}: {what}")
        self.query_one("#design-chosen", Static).update("\n".join(lines))
        if self._plot_args is not None:  # the reference steps show the chosen pair
            self._compute_plots(*self._plot_args)

    # --- plots ---------------------------------------------------------------------

    @work(thread=True, exclusive=True, group="plots")
    def _compute_plots(self, model: DelayTF, c: PIDTuning, ms: float | None) -> None:
        """The highlighted candidate's Nyquist curve, |S| and |T|, load step, and
        the reference step of each loop with its controller: the highlighted one
        for this loop, the chosen one for the other (so `_show_chosen` runs it
        again: a choice changes the other loop's step)."""
        from quadtank_tui.core.design.evaluate import settled_response
        from quadtank_tui.core.design.evaluation import load_size
        from quadtank_tui.core.design.frequency import frequency_grid, margins

        loop_tf = c.loop(model)
        m = margins(loop_tf)
        w = frequency_grid(loop_tf, points=600, decades=2.0)
        L = loop_tf.freqresp(w)
        keep = np.abs(L + 1.0) < 4.0
        load = settled_response(model, c, m, d=load_size(model))
        steps: dict[int, Response] = {}
        for i in (1, 2):
            other = self.loops[i]
            g, ci = (model, c) if i == self.loop else (other.design_model or other.model, other.chosen)
            if g is not None and ci is not None:
                try:
                    steps[i] = settled_response(g, ci, margins(ci.loop(g)), r=1.0)
                except ValueError:  # an unstable or unsimulable loop: not drawn
                    pass
        plots = DesignPlots(L[keep], w, 1.0 / (1.0 + L), L / (1.0 + L), load, steps, ms or m.Ms)
        self.app.call_from_thread(self._draw_plots, plots)

    def action_bode(self) -> None:
        """The other pair of plots: Nyquist and the reference steps, or |S| |T|
        and the load step."""
        self.frequency_view = not self.frequency_view
        if self._plots is not None:
            self._draw_plots(self._plots)

    def _redraw_plots(self) -> None:
        if self._plots is not None and self.is_attached:
            self._draw_plots(self._plots)

    def _draw_plots(self, plots: DesignPlots) -> None:
        self._plots = plots
        top, low = self.query_one("#nyquist", PlotView), self.query_one("#response", PlotView)
        dark, no_color = self.app.current_theme.dark, self.app.no_color
        for p in (top, low):
            p.figure.reset()
        top.set_class(not self.frequency_view, "-nyquist")  # short terminal: its figures in a few rows
        if self.frequency_view:
            draw_sensitivity(top, plots, dark, no_color)
            draw_load_step(low, plots.load, dark, no_color)
        else:
            draw_nyquist(top, plots, dark, no_color)
            draw_reference_steps(low, plots.steps, dark, no_color)
        top.refresh()
        low.refresh()

    # --- 2x2 -----------------------------------------------------------------------

    def action_design_2x2(self) -> None:
        if self.G is None:
            self.notify(f"no 2x2 model: {self.source} lacks an element", severity="error", markup=False)
            return
        G = self.typed_matrix() or self.G
        self._status(f"designing both loops on {self.source} ...")
        self._compute_2x2(G)

    @work(thread=True, exclusive=True, group="mimo")
    def _compute_2x2(self, G: Matrix, default: bool = False) -> None:
        """app.design.design_pair (what `quadtank design` gives) on the matrix of the
        moment it was asked for: self.G may change (a model typed) while the worker
        runs.  `default`: the screen's start (then each loop's table follows)."""
        from quadtank_tui.app.design import design_pair
        from quadtank_tui.core.design.pid_tuning import DesignError
        from quadtank_tui.core.design.mimo import format_check

        try:
            chk = design_pair(G, self.engine.snapshot().params.tsamp)
        except (DesignError, ValueError) as exc:
            self.app.call_from_thread(self.notify, str(exc), severity="error", markup=False)
            if default:
                self.app.call_from_thread(self.design_loop, self.loop)
            return
        self.app.call_from_thread(self._show_2x2, chk, format_check(chk), default)

    def _show_2x2(self, chk: MimoCheck, text: str, default: bool = False) -> None:
        for d in chk.loops:
            s = self.loops[d.loop]
            s.chosen, s.chosen_label = d.controller, f"default design on {d.how}"
            s.design_model, s.how = d.model, d.how
            s.rows, s.request = [], s.request + 1  # each table anew: checked with this pair
        self._show_chosen()
        self.query_one("#design-mimo", Static).update(text)
        verdict = "A applies it" if chk.stable else "the pair is UNSTABLE: choose other rows"
        self._status(f"{'default' if default else '2x2'} design ({chk.loops[0].controller.describe()}; "
                     f"{chk.loops[1].controller.describe()}): {verdict}")
        self.design_loop(self.loop)

    def action_check(self) -> None:
        c1, c2 = self.loops[1].chosen, self.loops[2].chosen
        G = self.typed_matrix()
        if G is None or c1 is None or c2 is None:
            self.notify("choose a controller for both loops first (Enter on a row, or 2)", severity="warning")
            return
        from quadtank_tui.core.design.mimo import lambda11, slowest_pole

        h = self.engine.snapshot().params.tsamp
        worst = slowest_pole(G, c1, c2, h)  # the loop sampled at the Ts in force
        verdict = "stable" if worst < 0 else "UNSTABLE"
        self.query_one("#design-mimo", Static).update(
            f"2x2 closed loop with the chosen pair, sampled at {h:g} s: {verdict} (slowest pole {worst:.3g} 1/s)\n"
            f"λ11(0) = {lambda11(G, 0.0).real:.3f}")

    # --- apply ---------------------------------------------------------------------

    def action_apply(self) -> None:
        """Apply shows the preview on the simulated plant first (ui.windows.design_preview);
        only its Apply (confirmed when the simulation misbehaves) reaches the engine."""
        pair = (self.loops[1].chosen, self.loops[2].chosen)
        if pair == (None, None):
            self.notify("nothing chosen: Enter on a candidate row, or 2 for the 2x2 design",
                        severity="warning")
            return
        from quadtank_tui.ui.windows.design_preview import DesignPreviewWindow, preview_request

        snap = self.engine.snapshot()
        try:
            request = preview_request(snap, pair, self.G)
        except (PlantError, DesignError, ValueError) as exc:
            self.notify(f"no preview, nothing applied: {exc}", severity="error", markup=False)
            return
        self.app.push_screen(DesignPreviewWindow(request, snap.params), lambda ok: self._apply(pair, ok))

    def _apply(self, pair: tuple[PIDTuning | None, PIDTuning | None], ok: bool | None) -> None:
        from quadtank_tui.core.design.apply import controller_values, describe_changes

        if not ok:
            self.notify("not applied", timeout=3)
            return
        values = controller_values(pair)
        changes = describe_changes(self.engine.snapshot().params, values)
        self.send(SetParams(values))
        self.notify("\n".join(changes) or "already in the matrix", title="Applied", timeout=6)

    def action_export_figure(self) -> None:
        """Each loop with a chosen controller, on its model, drawn in a worker."""
        from pathlib import Path

        from quadtank_tui.ui.figure_export import design_builder, export

        h = self.engine.snapshot().params.tsamp
        loops = []
        for i, s in self.loops.items():
            g = s.design_model or s.model
            if s.chosen is not None and g is not None:
                loops.append((f"loop {i} on {s.how or f'g{i}{i}'}", g, s.chosen, h))
        if not loops:
            self.notify("choose a controller first (Enter on a row, or 2)", severity="warning")
            return
        export(self, Path(self.engine.logs_dir), "design",
               design_builder(loops, f"models: {self.source}"))

    def _status(self, text: str, *, error: bool = False) -> None:
        """The status line: `text` as it is (it quotes typed models and file
        names, never read as markup), red for an error."""
        # The blanks end the bold run (a viewer may drop a run's leading blanks)
        line = Content.assemble(("Design  ", "bold"), (text, "red") if error else text)
        self.query_one("#design-status", Static).update(line)


def _key(row_key: Any) -> str | None:
    """A DataTable event's row key as text; Textual sends RowHighlighted(cursor_row=-1,
    row_key=None) when the cursor is on no row (the table cleared or rebuilt under it):
    that crashed the screen three times in 20,000 random keys."""
    return None if row_key is None else row_key.value
