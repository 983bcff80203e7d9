"""The chosen pair of controllers tried on the simulated plant before Apply.

The Design screen's Apply opens this window; it runs core.design.preview in a
worker (a step of 0.1 on each loop in turn, on the nonlinear model of the plant in
use, from the levels and inputs of the moment, at the sampling time in force, the
pumps limited), with a progress bar, then shows the predicted (linear sampled
design) and simulated curves and figures.  Apply hands back True; when the
simulation is unstable, limit-cycles or holds a pump at a limit for more than a
fifth of the window, Apply first asks an explicit question that says so.  Esc or
Cancel hands back None: nothing is applied.
"""

from __future__ import annotations

from functools import partial
from typing import Sequence

import numpy as np

from textual import work
from textual.app import ComposeResult
from textual.containers import Horizontal, VerticalScroll
from textual.geometry import Size
from textual.widgets import Button, ProgressBar, Static

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.robust import Robustness
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.app.design import PreviewPlan, preview_plan
from quadtank_tui.core.design.preview import Preview, PreviewStep, format_preview
from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.colours import BLUE, RED
from quadtank_tui.ui.widgets import plot_kit as kit
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.widgets.plot_kit import Series
from quadtank_tui.ui.widgets.plot_view import PlotView
from quadtank_tui.ui.widgets.sized import PacksForSize
from quadtank_tui.ui.windows.base import Choice, ChoiceWindow, Window


def preview_request(snap: Snapshot, pair: tuple[PIDTuning | None, PIDTuning | None],
                    G: Sequence[Sequence[DelayTF]] | None) -> PreviewPlan:
    """The preview of `pair` (None: the loop's controller in force) on the plant in use
    (app.design.preview_plan, the one `quadtank design` runs): from the levels and
    inputs of the moment while the process runs, else from the parameters'
    operating point; at the sampling time in force; each step until it settles."""
    from quadtank_tui.core.design.apply import in_force
    from quadtank_tui.core.plants.common import FULL_SCALE_V

    p = snap.params
    plant = p.process_plant()
    chosen = (pair[0] or in_force(p, 1), pair[1] or in_force(p, 2))
    start = None
    if snap.state == "Run":
        start = (tuple(y * FULL_SCALE_V * st.hi / out.hi for y, st, out in zip(snap.y, plant.states, plant.outputs)),
                 tuple(u * s.full_scale for u, s in zip(snap.u, plant.inputs)))
    return preview_plan(p, chosen, G, p.tsamp, start=start)


#: Terminal rows below which the window is laid out short (windows.tcss).
SHORT = 32


class DesignPreviewWindow(PacksForSize, Window[bool]):
    """Predicted and simulated steps of the chosen pair; Apply or Cancel."""

    def __init__(self, request: PreviewPlan, params: Parameters | None = None) -> None:
        """`params`: the setting whose plant the robustness spread is drawn about
        (app.design.robustness_of; None: no spread)."""
        super().__init__("Preview on the simulated plant")
        self.request = request
        self.params = params
        self.result: Preview | None = None
        self.spread: Robustness | None = None
        self.spread_note = ""

    def compose_body(self) -> ComposeResult:
        r = self.request
        yield Static(f"{r.plant.title}: step 0.1 on each loop until it settles, sampled at {r.h:g} s, "
                     "pumps 0..10 V; y1 after the r1 step, y2 after the r2 step; the design's prediction "
                     "dotted over the nonlinear simulation",
                     id="preview-what", markup=False)
        yield ProgressBar(total=100, show_eta=False, id="preview-progress")
        with Horizontal(id="preview-plots"):
            for i in (1, 2):
                yield PlotView(id=f"preview-loop{i}", classes="preview-plot")
        with VerticalScroll(id="preview-figures-box"):
            yield Static("", id="preview-figures", markup=False)

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Apply", id="apply", variant="primary", disabled=True)
        yield KeyButton("Cancel", id="cancel")

    def on_mount(self) -> None:
        for i in (1, 2):
            self.query_one(f"#preview-loop{i}", PlotView).border_title = f"y{i}: simulating"
        self.query_one("#cancel", Button).focus()
        self._simulate()

    def pack(self, size: Size) -> None:
        """Below SHORT rows the plots shrink and the figures scroll, so Apply and
        Cancel stay on the screen (at 80x24 they were below its edge)."""
        self.set_class(size.height < SHORT, "-short")

    @work(thread=True, exclusive=True, group="preview")
    def _simulate(self) -> None:
        r = self.request
        try:
            pv = r.run(progress=lambda f: self.app.call_from_thread(self._progress, 0.8 * f))
        except (DesignError, PlantError, ValueError) as exc:
            self.app.call_from_thread(self._failed, str(exc))
            return
        if self.params is not None:
            from quadtank_tui.app.design import robustness_of

            try:
                self.spread = robustness_of(self.params, r, pv)
            except ValueError as exc:
                self.spread_note = f"no robustness spread: {exc}"
        self.app.call_from_thread(self._show, pv)

    @property
    def warnings(self) -> list[str]:
        """The nominal preview's warnings, then the spread's (Apply asks again on any)."""
        out = list(self.result.warnings) if self.result is not None else []
        return out + (self.spread.warnings if self.spread is not None else [])

    def _progress(self, fraction: float) -> None:
        self.query_one(ProgressBar).update(progress=round(100 * fraction, 1))

    def _failed(self, why: str) -> None:
        self.query_one(ProgressBar).display = False
        self.show_message(f"no preview: {why}")

    def _redraw_step(self, plot: PlotView, step: PreviewStep) -> None:
        """One step's plot again, for the size it has now (PlotView.relayout)."""
        if self.is_attached:
            draw_preview_step(plot, step, self.app.current_theme.dark, self.app.no_color)

    def _show(self, pv: Preview) -> None:
        self.result = pv
        self.query_one(ProgressBar).display = False
        dark, no_color = self.app.current_theme.dark, self.app.no_color
        for s in pv.steps:
            plot = self.query_one(f"#preview-loop{s.loop}", PlotView)
            draw_preview_step(plot, s, dark, no_color)
            plot.relayout = partial(self._redraw_step, plot, s)
        from quadtank_tui.core.design.robust import format_robustness

        text = format_preview(pv)
        if self.spread is not None:
            text += "\nrobustness " + format_robustness(self.spread)
        elif self.spread_note:
            text += "\n" + self.spread_note
        self.query_one("#preview-figures", Static).update(text)
        apply = self.query_one("#apply", Button)
        apply.disabled = False
        if self.warnings:
            apply.label = "Apply anyway..."
            apply.variant = "error"
            self.show_message("; ".join(self.warnings))
        apply.focus()

    def action_apply(self) -> None:
        pv = self.result
        if pv is None:
            return
        if not self.warnings:
            self.dismiss(True)
            return
        question = ("On the simulated plant:\n" + "\n".join(f"  {w}" for w in self.warnings)
                    + "\nApply these controllers to the process anyway?")

        def answered(answer: str | None) -> None:
            if answer == "apply":
                self.dismiss(True)

        self.app.push_screen(ChoiceWindow("Apply anyway?", question,
                                          (Choice("cancel", "Do not apply"),
                                           Choice("apply", "Apply anyway", "error"))), answered)


def draw_preview_step(plot: PlotView, step: PreviewStep, dark: bool, no_color: bool) -> None:
    """One loop's step: the simulation solid and the design's prediction dotted
    over it (plot_kit's lines, ticks and legend, as on the Design screen: issues
    28, 43).  The prediction is drawn last: where a good design's prediction lies
    on the simulation the cells they share take the two colours in turn, so the
    student sees that the two agree."""
    predicted, simulated = kit.styles([Series("predicted", BLUE, dotted=True), Series("simulated", RED)],
                                      dark=dark, no_color=no_color)
    width, height = plot.content_size.width, plot.content_size.height
    fig = plot.figure
    fig.reset()
    curves = [step.simulated]
    kit.draw(fig, step.t, step.simulated, simulated)
    if step.predicted is not None:  # last: where the two agree, its dots still show
        kit.draw(fig, step.t, step.predicted, predicted)
        curves.append(step.predicted)
    both = np.concatenate(curves)
    both = both[np.isfinite(both)]
    lo, hi = (float(both.min()), float(both.max())) if len(both) else (0.0, 1.0)
    kit.axes(fig, (0.0, float(step.t[-1])), (lo, hi), width, height, xlabel="t (s)")
    shown = [simulated, predicted] if step.predicted is not None else [simulated]
    plot.border_title = kit.legend(shown, f"y{step.loop}: ")  # the window's line says which step
    plot.refresh()
