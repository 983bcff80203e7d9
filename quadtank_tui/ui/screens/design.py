"""The Design screen (B3): a PI/PID for each loop from a model, compared in a
table in the style of Andersson's section 4.4, checked on the 2x2 process, and
applied to the running controller matrix.

The models start as the physical linearization of the current setting (g11 and
g22 at its operating levels), or as an identified model's G11 and G22 when the
Identify screen opens this one, and can be typed over (`1.66*exp(-2.4*s)/(1.07*s+1)^3`).
Designing and evaluating nine candidates takes a second or two, so it runs in a
worker; the process keeps running underneath.  Nothing reaches the engine until
Apply (A): then one SetParams, bumpless like any parameter change, and a
notification of what changed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Sequence

import numpy as np
from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.widgets import DataTable, Footer, Input, Label, Static
from textual_plotext import PlotextPlot

from quadtank_tui.core.delaytf import DelayTF, ModelError
from quadtank_tui.core.design.controller import PID, DesignError
from quadtank_tui.core.plant import PlantError
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.screens.sending import CommandSender

if TYPE_CHECKING:  # the design core loads when the screen first computes (start-up time)
    from quadtank_tui.core.design.mimo import Matrix, MimoCheck
    from quadtank_tui.core.design.simulate import Response
    from quadtank_tui.core.design.table import Candidate

#: Fixed widths (a space included): the header never depends on when the rows came in.
COLUMNS = (("candidate", 14), ("Kc", 7), ("Ti", 7), ("Td", 5), ("IAE", 7), ("Emax", 6),
           ("u_os", 5), ("φm", 4), ("Lm", 6), ("Am", 6), ("Ms", 5))
HELP = "Tab to a model, type it, Enter: its candidates · Enter on a row: choose it for the loop"


@dataclass
class LoopState:
    """What the screen holds for one loop (the UI keeps no control logic: the
    numbers come from core.design)."""

    text: str = ""
    model: DelayTF | None = None
    rows: list[Candidate] = field(default_factory=list)
    chosen: PID | None = None
    chosen_label: str = ""


def _num(x: float | None, digits: int = 4) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"


class DesignScreen(CommandSender):
    """Models per loop, the candidates table, Nyquist and load-step plots, the
    2x2 check, Apply."""

    CSS_PATH = "../styles/design.tcss"
    AUTO_FOCUS = "#design-table"  # letter keys act; Tab or a click reaches a model

    BINDINGS = [
        Binding("escape", "main", "Main"),
        Binding("l", "switch_loop", "Loop 1/2"),
        Binding("2", "design_2x2", "2x2 design"),
        Binding("x", "check", "2x2 check"),
        Binding("A", "apply", "Apply"),
        Binding("p", "physical", "Physical models", show=False),
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

    def compose(self) -> ComposeResult:
        yield Static(id="design-status")
        with Horizontal(id="design-models"):
            for i in (1, 2):
                yield Label(f"Loop {i} (y{i} from u{i})", classes="model-label")
                yield Input(id=f"model-{i}", classes="model")
        with Horizontal(id="design-body"):
            with Vertical(id="design-left"):
                table: DataTable[str] = DataTable(id="design-table", cursor_type="row", zebra_stripes=False,
                                                  cell_padding=0)
                table.border_title = "Candidates"
                yield table
                yield Static(id="design-chosen")
                yield Static(id="design-mimo")
            with Vertical(id="design-right"):
                yield PlotextPlot(id="nyquist")
                yield PlotextPlot(id="response")
        yield Static(HELP, id="design-help")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#design-table", DataTable)
        for label, width in COLUMNS:
            table.add_column(label, key=label, width=width)
        self.query_one("#nyquist", PlotextPlot).border_title = "Nyquist L(iω), circle 1/Ms around -1"
        self.query_one("#response", PlotextPlot).border_title = "Load step at the input: y (blue), u (red)"
        if self.identified is not None:
            self.action_identified()
        else:
            self.action_physical()

    # --- models ----------------------------------------------------------------------

    def action_physical(self) -> None:
        """Both loops' models from the physical linearization of the current setting."""
        from quadtank_tui.core.design.controller import DesignError
        from quadtank_tui.core.design.mimo import model_in_use
        from quadtank_tui.core.plant import PlantError

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
            self.loops[i] = LoopState(text="" if g is None else str(g), model=g)
            self.query_one(f"#model-{i}", Input).value = "" if g is None else str(g)
        self.design_loop(self.loop)

    @on(Input.Submitted, ".model")
    def model_typed(self, event: Input.Submitted) -> None:
        from quadtank_tui.core.design.expr import parse_model

        loop = 1 if event.input.id == "model-1" else 2
        try:
            g = parse_model(event.value)
        except ModelError as exc:
            # The message quotes what was typed: plain text, never markup.
            self.notify(str(exc), title=f"Loop {loop} model", severity="error", timeout=8, markup=False)
            return
        self.loops[loop] = LoopState(text=event.value, model=g)
        self.loop = loop
        self.design_loop(loop)

    # --- the table -------------------------------------------------------------------

    def design_loop(self, loop: int) -> None:
        self._status(f"designing loop {loop}: nine candidates ...")
        self.query_one("#design-table", DataTable).clear()
        self._compute_table(loop, self.loops[loop].model)

    @work(thread=True, exclusive=True, group="table")
    def _compute_table(self, loop: int, model: DelayTF | None) -> None:
        from quadtank_tui.core.design.table import candidates

        if model is None:
            return
        try:
            snap = self.engine.snapshot()  # the loop as it runs: its sampling time, its pump's input
            rows = candidates(model, h=snap.params.tsamp, u0=snap.u[loop - 1] if snap.state == "Run" else 0.5)
        except ValueError as exc:  # a model the evaluation cannot simulate: one line, no crash
            self.app.call_from_thread(self._status, f"loop {loop}: {exc}", error=True)
            return
        self.app.call_from_thread(self._show_table, loop, model, rows)

    def _show_table(self, loop: int, model: DelayTF, rows: list[Candidate]) -> None:
        state = self.loops[loop]
        if state.model is not model:
            return  # a newer model was typed meanwhile
        state.rows = rows
        if loop == self.loop:
            self._fill_table()
        self._status(f"loop {loop}: {len(rows)} candidates on {model}")

    def _fill_table(self) -> None:
        table = self.query_one("#design-table", DataTable)
        table.clear()
        table.border_title = f"Candidates, loop {self.loop}"
        for n, r in enumerate(self.loops[self.loop].rows):
            c, e = r.controller, r.evaluation
            if c is None or e is None:  # the reason shows when the row is highlighted
                table.add_row(r.label, "n/a", *["-"] * 9, key=str(n))
                continue
            if not e.stable:
                table.add_row(r.label, _num(c.Kc), _num(c.Ti), _num(c.Td, 3), "unstable",
                              *[""] * 6, key=str(n))
                continue
            table.add_row(r.label, _num(c.Kc), _num(c.Ti), _num(c.Td, 3), _num(e.IAE),
                          _num(e.Emax, 3), f"{e.u_overshoot:.2f}", f"{e.phase_margin_deg:.0f}",
                          _num(e.delay_margin, 3), _num(e.gain_margin, 3), f"{e.Ms:.2f}", key=str(n))

    def action_switch_loop(self) -> None:
        self.loop = 3 - self.loop
        state = self.loops[self.loop]
        if state.rows:
            self._fill_table()
        else:
            self.design_loop(self.loop)
        self._show_chosen()

    def _row(self, key: str | None) -> Candidate | None:
        rows = self.loops[self.loop].rows
        if key is None or not key.isdigit() or int(key) >= len(rows):
            return None
        return rows[int(key)]

    @on(DataTable.RowHighlighted, "#design-table")
    def row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        row = self._row(event.row_key.value)
        model = self.loops[self.loop].model
        if row is not None and row.error:
            self._status(f"{row.label}: {row.error}")
        if row is not None and row.controller is not None and model is not None:
            self._compute_plots(model, row.controller, row.parameter if row.method != "lambda" else None)

    @on(DataTable.RowSelected, "#design-table")
    def row_selected(self, event: DataTable.RowSelected) -> None:
        row = self._row(event.row_key.value)
        if row is None or row.controller is None:
            self.notify("this candidate has no controller", severity="warning")
            return
        state = self.loops[self.loop]
        state.chosen, state.chosen_label = row.controller.rounded(), row.label
        self._show_chosen()

    def _show_chosen(self) -> None:
        lines = []
        for i in (1, 2):
            s = self.loops[i]
            what = f"{s.chosen.describe()}  ({s.chosen_label})" if s.chosen else "[dim]none chosen[/]"
            mark = "▸" if i == self.loop else " "
            lines.append(f"{mark} loop {i}: {what}")
        self.query_one("#design-chosen", Static).update("\n".join(lines))

    # --- plots ---------------------------------------------------------------------

    @work(thread=True, exclusive=True, group="plots")
    def _compute_plots(self, model: DelayTF, c: PID, ms: float | None) -> None:
        from quadtank_tui.core.design.evaluate import load_size, settled_response
        from quadtank_tui.core.design.frequency import frequency_grid, margins

        loop_tf = c.loop(model)
        m = margins(loop_tf)
        w = frequency_grid(loop_tf, points=600, decades=2.0)
        L = loop_tf.freqresp(w)
        keep = np.abs(L + 1.0) < 4.0
        resp = settled_response(model, c, m, d=load_size(model))
        self.app.call_from_thread(self._draw_plots, L[keep], resp, ms or m.Ms)

    def _draw_plots(self, L: np.ndarray, resp: Response, ms: float) -> None:
        ny = self.query_one("#nyquist", PlotextPlot)
        plt = ny.plt
        plt.clear_data()
        plt.plot(L.real.tolist(), L.imag.tolist(), color="blue", marker="braille")
        th = np.linspace(0, 2 * np.pi, 120)
        plt.plot((-1 + np.cos(th) / ms).tolist(), (np.sin(th) / ms).tolist(), color="red", marker="braille")
        plt.xlim(-3.0, 1.0)
        plt.ylim(-2.0, 1.0)
        ny.refresh()
        rp = self.query_one("#response", PlotextPlot)
        plt = rp.plt
        plt.clear_data()
        n = len(resp.t)
        step = max(1, n // 200)
        scale = abs(resp.d) or 1.0
        plt.plot(resp.t[::step].tolist(), (resp.y[::step] / scale).tolist(), color="blue", marker="braille")
        plt.plot(resp.t[::step].tolist(), (resp.u[::step] / scale).tolist(), color="red", marker="braille")
        rp.refresh()

    # --- 2x2 -----------------------------------------------------------------------

    def action_design_2x2(self) -> None:
        if self.G is None:
            self.notify(f"no 2x2 model: {self.source} lacks an element", severity="error", markup=False)
            return
        self._status(f"designing both loops on {self.source} ...")
        self._compute_2x2(self.G)

    @work(thread=True, exclusive=True, group="mimo")
    def _compute_2x2(self, G: Matrix) -> None:
        """On the matrix of the moment it was asked for: self.G may change (a model
        typed) while the worker runs."""
        from quadtank_tui.core.design.controller import DesignError
        from quadtank_tui.core.design.mimo import design_2x2, format_check

        try:
            chk = design_2x2(G, h=self.engine.snapshot().params.tsamp)
        except DesignError as exc:
            self.app.call_from_thread(self.notify, str(exc), severity="error", markup=False)
            return
        self.app.call_from_thread(self._show_2x2, chk, format_check(chk))

    def _show_2x2(self, chk: MimoCheck, text: str) -> None:
        for d in chk.loops:
            s = self.loops[d.loop]
            s.chosen, s.chosen_label = d.controller, f"2x2 design on {d.how}"
        self._show_chosen()
        self.query_one("#design-mimo", Static).update(text)
        self._status("2x2 design done: A applies it")

    def action_check(self) -> None:
        c1, c2 = self.loops[1].chosen, self.loops[2].chosen
        if self.G is None or c1 is None or c2 is None:
            self.notify("choose a controller for both loops first (Enter on a row, or 2)", severity="warning")
            return
        from quadtank_tui.core.design.mimo import lambda11, slowest_pole

        h = self.engine.snapshot().params.tsamp
        worst = slowest_pole(self.G, c1, c2, h)  # the loop sampled at the Ts in force
        verdict = "stable" if worst < 0 else "UNSTABLE"
        self.query_one("#design-mimo", Static).update(
            f"2x2 closed loop with the chosen pair, sampled at {h:g} s: {verdict} (slowest pole {worst:.3g} 1/s)\n"
            f"λ11(0) = {lambda11(self.G, 0.0).real:.3f}")

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
        self.app.push_screen(DesignPreviewWindow(request), lambda ok: self._apply(pair, ok))

    def _apply(self, pair: tuple[PID | None, PID | None], ok: bool | None) -> None:
        from quadtank_tui.core.design.apply import controller_values, describe_changes

        if not ok:
            self.notify("not applied", timeout=3)
            return
        values = controller_values(pair)
        changes = describe_changes(self.engine.snapshot().params, values)
        self.send(SetParams(values))
        self.notify("\n".join(changes) or "already in the matrix", title="Applied", timeout=6)

    def action_main(self) -> None:
        self.app.pop_screen()

    def _status(self, text: str, *, error: bool = False) -> None:
        """The status line: `text` as it is (it quotes typed models and file
        names, never read as markup), red for an error."""
        line = Content.assemble(("Design", "bold"), "  ", (text, "red") if error else text)
        self.query_one("#design-status", Static).update(line)

