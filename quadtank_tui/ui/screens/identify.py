"""The Identify screen (issue 12; Nunes 3, Andersson 2): models from logged
experiments without leaving the terminal.  The process keeps running behind it.

Choose one or more logs from `logs/` (the one just saved is ticked), a method and
its structure, fit (in a worker: the screen never freezes; Esc or `c` cancels),
then see the measured and model outputs overlaid, the residual autocorrelation,
the coherence or the gain of the spectral estimate against the model's, and the table that sets the identified gains, time constants and
zeros beside the physical linearization.  `k` keeps the model as JSON next to the
first log (what design reads); `d` opens the Design screen on the fitted G11 and G22.  All numbers come from core/identify; this screen
only renders them.

The method "physical" fits the constants ticked in a second list (those of the
plant in use) with the plant's own simulator, a progress bar while it runs; the
last of two or more ticked logs is held out and the model is overlaid on it; `k`
saves the constants as NAME.par next to the first log, of the kind of the `.par`
in use, and asks (a second `k`) before overwriting one (ui/screens/identify_physical).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.geometry import Size
from textual.widgets import DataTable, ProgressBar, SelectionList, Static
from textual.worker import get_current_worker

from quadtank_tui.ui.colours import BLUE, GREY, RED, SIGNALS
from quadtank_tui.ui.screens import identify_physical as fitui
from quadtank_tui.ui.screens.sending import COMPACT_WIDTH
from quadtank_tui.ui.widgets import plot_kit as kit
from quadtank_tui.ui.widgets.key_footer import KeyFooter
from quadtank_tui.ui.widgets.plot_kit import Series
from quadtank_tui.ui.widgets.plot_view import PlotView
from quadtank_tui.ui.widgets.sized import PacksForSize

if TYPE_CHECKING:  # the analysis stack loads with the first fit, not with the app
    from quadtank_tui.engine.handle import EngineHandle
    from quadtank_tui.core.identify.compare import Comparison
    from quadtank_tui.core.identify.experiment import Element, Identification
    from quadtank_tui.core.parameters import Parameters
    from quadtank_tui.core.plants import Plant

METHODS = ("oe", "step", "n4sid", "arx", "physical")
LOWER_PLOTS = ("residuals", "coherence", "frequency")


@dataclass(frozen=True)
class FitView:
    """What a finished fit hands the screen: the identification, the comparison (or
    None), the physical model's name, and per element its residual autocorrelation
    and coherence, and its gain |G(iw)| from the spectral estimate and from the model."""

    ident: Identification
    comparison: Comparison | None
    physical: str
    residuals: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, float]]
    coherence: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
    frequency: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]]


def compute(paths: list[str], method: str, structure: int, cancel: threading.Event,
            progress: Callable[[int], None] = lambda k: None) -> FitView:
    """Read the logs, identify, compare, and prepare the plots (run in a worker);
    `progress(k)` is told when the k-th element's fit starts."""
    from quadtank_tui.core.identify.compare import closest_setting, compare
    from quadtank_tui.core.identify.experiment import Options, Record, identify
    from quadtank_tui.core.identify.validation import autocorrelation, coherence, spectral_estimate
    from quadtank_tui.files.log_reader import read_log

    records = []
    for p in paths:
        log = read_log(p)
        if log.tsamp is None:
            raise ValueError(f"{p}: no TSamp in the header: the sampling time is needed")
        records.append(Record(p, log.tsamp, log.columns()))
    started = [0]

    def stop() -> bool:
        started[0] += 1
        progress(started[0])
        return cancel.is_set()

    ident = identify(records, Options(method=method, structure=structure), cancel=stop)
    setting = closest_setting(ident.operating_point)
    cmp = None
    if set(ident.inputs) <= {"u1", "u2"} and set(ident.outputs) <= {"y1", "y2"}:
        cmp = compare(ident.operating_point, setting.params, ident.system.static_gains,
                      ident.inputs, ident.outputs, setting.op.u)
    residuals, coh, freq = {}, {}, {}
    for key, e in ident.elements.items():
        k = e.split
        res = e.y[k:] - e.ym[k:]
        if np.ptp(res) > 0:
            r = autocorrelation(res)
            residuals[key] = (r.lags.astype(float), r.value, r.band)
        f, c = coherence(e.u - e.u[0], e.y - e.y[0], ident.h)
        coh[key] = (f, c)
        w, g = spectral_estimate(e.u - e.u[0], e.y - e.y[0], ident.h)
        keep = (w > 0) & (w <= 2 * np.pi * 0.1)
        freq[key] = (w[keep], np.abs(g[keep]), np.abs(e.tf.freqresp(w[keep])))
    return FitView(ident, cmp, setting.title, residuals, coh, freq)


class IdentifyScreen(PacksForSize):
    """Fit models to logs; Esc returns to Main."""

    AUTO_FOCUS = "#logs"

    BINDINGS = [
        Binding("escape", "back", "Back"),
        Binding("f", "fit", "Fit"),
        Binding("c", "cancel", "Cancel fit", show=False),  # the status says it while fitting
        Binding("m", "method", "Method"),
        Binding("n", "structure", "Structure"),
        Binding("e", "element", "Element"),
        Binding("v", "lower_plot", "Residuals/coherence/gain"),
        Binding("k", "keep", "Keep model"),
        Binding("d", "design", "Design"),
        Binding("E", "export_figure", "Export figure", show=False,
                tooltip="The fit's validation, residual autocorrelation and coherence as a PNG next to the first log"),
        Binding("F5", "rescan", "Rescan logs", show=False),
    ]

    def __init__(self, logs_dir: Path | str = "logs", last_log: str = "",
                 engine: EngineHandle | None = None) -> None:
        """`engine`: the running process, for the Design screen (`d`)."""
        super().__init__()
        self.engine = engine
        self.logs_dir = Path(logs_dir)
        self.last_log = last_log
        self.method = "oe"
        self.structure = 1
        self.element_index = 0
        self.lower = LOWER_PLOTS[0]
        self.view: FitView | None = None
        #: the last physical fit (method "physical"), and a .par that `k` would overwrite
        self.physical: fitui.PhysicalView | None = None
        #: What drew the plots last (_preview of a log, or _draw): a resize draws it again.
        self._drawn: Callable[[], None] | None = None
        self._overwrite: Path | None = None
        self._cancel = threading.Event()
        self._fitting = False

    def compose(self) -> ComposeResult:
        yield Static("", id="identify-status")
        yield ProgressBar(id="fit-progress", show_eta=False)
        with Horizontal(id="identify-body"):
            with Vertical(id="identify-left"):
                yield SelectionList[str](id="logs")
                yield Static("", id="choice")
                yield SelectionList[str](id="free")
                yield DataTable(id="compare", cursor_type="none", zebra_stripes=True)
                yield Static("", id="zeros")
            with Vertical(id="identify-right"):
                yield PlotView(id="outputs")
                yield PlotView(id="lower")
        yield KeyFooter()

    def pack(self, size: Size) -> None:
        self.set_class(size.width < COMPACT_WIDTH, "-compact")

    def on_resize(self) -> None:
        # Besides the packing (PacksForSize): the plots are decimated for their width
        # when drawn, so they are drawn again once the new layout has given them theirs.
        self.call_after_refresh(self._redraw)

    def _redraw(self) -> None:
        """The plots again, as last drawn (a log's preview, or the fit's)."""
        if self.is_attached and self._drawn is not None:
            self._drawn()

    def on_mount(self) -> None:
        self.query_one("#logs", SelectionList).border_title = Content(f"Logs in {self.logs_dir}/ (space ticks)")
        self.query_one("#compare", DataTable).border_title = "Identified | physical"
        free = self.query_one("#free", SelectionList)
        plant = self._params().process_plant()
        free.border_title = Content(f"Constants to fit ({plant.kind}; space ticks)")
        free.border_subtitle = "2+ logs ticked: the last validates"
        ticked = fitui.default_free(plant)
        for name in plant.values():
            free.add_option((Content(name), name, name in ticked))
        self.query_one("#fit-progress", ProgressBar).display = False
        self.action_rescan()
        self._show_choice()
        self._status("Tick the logs (SIMO: one per input; n4sid: one MIMO log), choose the method, f to fit.")
        self._draw()

    # --- choices --------------------------------------------------------------------

    def on_selection_list_selection_highlighted(self, event: SelectionList.SelectionHighlighted) -> None:
        """Before a fit, the top plot shows the highlighted log's signals."""
        if self.view is None and not self._fitting:
            self._preview(str(event.selection.value))

    def _preview(self, path: str) -> None:
        from quadtank_tui.files.log_reader import read_log

        self._drawn = partial(self._preview, path)
        top = self.query_one("#outputs", PlotView)
        top.figure.reset()
        try:
            log = read_log(path)
        except ValueError as exc:
            self._status(str(exc), error=True)
            return
        h = log.tsamp or 1.0
        t = np.arange(log.rows) * h
        shown = [n for n in ("y1", "y2", "u1", "u2") if n in log.variables]
        # levels solid, the inputs that moved them dotted (the same hue per loop)
        drawn = kit.styles([Series(n, SIGNALS[n], dotted=n.startswith("u")) for n in shown],
                           dark=self.app.current_theme.dark, no_color=self.app.no_color)
        width, height = top.content_size.width, top.content_size.height
        for st in drawn:
            kit.draw(top.figure, t, log[st.series.label], st)
        if shown:
            values = np.concatenate([log[n] for n in shown])
            kit.axes(top.figure, (0.0, float(t[-1])), (float(values.min()), float(values.max())), width, height,
                     xlabel="t (s)")
        top.border_title = kit.legend(drawn, f"{Path(path).name}: {log.rows} rows at {h:g} s: ")
        top.refresh()

    def action_rescan(self) -> None:
        sel = self.query_one("#logs", SelectionList)
        sel.clear_options()
        logs = sorted(self.logs_dir.glob("*.log")) if self.logs_dir.is_dir() else []
        last = Path(self.last_log).resolve() if self.last_log else None
        for p in logs:
            sel.add_option((Content(p.name), str(p), last is not None and p.resolve() == last))
        if logs:
            sel.highlighted = 0

    def _show_choice(self) -> None:
        extra = f"  structure {self.structure} (n)" if self.method == "step" else ""
        if self.method == "physical":
            extra = "  Tab: the constants"
        self.query_one("#choice", Static).update(f"Method [b]{self.method}[/] (m){extra}")
        self.query_one("#free", SelectionList).display = self.method == "physical"
        self.query_one("#compare", DataTable).display = self.method != "physical" or self.physical is not None

    def _params(self) -> Parameters:
        """The parameters in use: the running process's, the built-in ones without it."""
        from quadtank_tui.core.parameters import PRESET

        return self.engine.snapshot().params if self.engine is not None else PRESET

    def action_method(self) -> None:
        if self._fitting:
            return
        self.method = METHODS[(METHODS.index(self.method) + 1) % len(METHODS)]
        self._show_choice()
        if self.method == "physical" or self.method == METHODS[0]:
            self._table()
            self._draw()

    def action_structure(self) -> None:
        self.structure = self.structure % 5 + 1
        self._show_choice()

    def action_element(self) -> None:
        if self.method == "physical" and self.physical is not None:
            self.element_index += 1
            self._draw()
        elif self.view is not None:
            self.element_index = (self.element_index + 1) % len(self.view.ident.elements)
            self._draw()

    def action_lower_plot(self) -> None:
        self.lower = LOWER_PLOTS[(LOWER_PLOTS.index(self.lower) + 1) % len(LOWER_PLOTS)]
        self._draw()

    def action_back(self) -> None:
        self.action_cancel()
        self.app.pop_screen()

    # --- the fit ----------------------------------------------------------------------

    def action_fit(self) -> None:
        paths = list(self.query_one("#logs", SelectionList).selected)
        if not paths:
            self._status("Tick at least one log (space) first.", error=True)
            return
        if self._fitting:
            return
        if self.method == "physical":
            self._fit_physical(paths)
            return
        self._cancel = threading.Event()
        self._fitting = True
        self._status(f"Fitting {self.method} to {', '.join(Path(p).name for p in paths)} ... (c cancels)")
        self._run_fit(paths, self.method, self.structure, self._cancel)

    def _fit_physical(self, paths: list[str]) -> None:
        free = tuple(self.query_one("#free", SelectionList).selected)
        if not free:
            self._status("Tick at least one constant to fit (Tab to the constants, space).", error=True)
            return
        plant = self._params().process_plant()
        bar = self.query_one("#fit-progress", ProgressBar)
        bar.update(total=fitui.evaluations_bound(len(free), 4), progress=0)
        bar.display = True
        self._cancel = threading.Event()
        self._fitting = True
        self._overwrite = None
        self._status(f"Fitting {', '.join(free)} of the {plant.kind} to "
                     f"{', '.join(Path(p).name for p in paths)} ... (c cancels)")
        self._run_physical(paths, plant, free, self._cancel)

    @work(thread=True, exclusive=True, group="fit")
    def _run_physical(self, paths: list[str], plant: Plant, free: tuple[str, ...],
                      cancel: threading.Event) -> None:
        def progress(k: int, rms: float) -> None:
            self.app.call_from_thread(self._progress, k, rms)

        try:
            view = fitui.compute_physical(paths, plant, free, cancel, progress)
        except ValueError as exc:  # bad logs, another plant's log, no convergence, cancelled: one line
            self.app.call_from_thread(self._failed, "cancelled" if cancel.is_set() else str(exc))
            return
        if cancel.is_set():
            self.app.call_from_thread(self._failed, "cancelled")
        else:
            self.app.call_from_thread(self._done_physical, view)

    def _progress(self, k: int, rms: float) -> None:
        if self._fitting:
            self.query_one("#fit-progress", ProgressBar).update(progress=k)
            self._status(f"Fitting physical: {k} simulations, RMS {rms:.3g} V ... (c cancels)")

    def _done_physical(self, view: fitui.PhysicalView) -> None:
        self._fitting = False
        self.query_one("#fit-progress", ProgressBar).display = False
        self.physical = view
        self.element_index = 0
        self._status(fitui.summary(view), keys="  e: next output  k: save as .par")
        self._show_choice()
        self._table()
        self._draw()

    @work(thread=True, exclusive=True, group="fit")
    def _run_fit(self, paths: list[str], method: str, structure: int, cancel: threading.Event) -> None:
        def progress(k: int) -> None:
            self.app.call_from_thread(self._status, f"Fitting {method}: element {k} ... (c cancels)")

        try:
            view = compute(paths, method, structure, cancel, progress)
        except ValueError as exc:  # bad logs, no step, constant input: one line
            message = "cancelled" if cancel.is_set() else str(exc)
            self.app.call_from_thread(self._failed, message)
            return
        if not get_current_worker().is_cancelled and not cancel.is_set():
            self.app.call_from_thread(self._done, view)
        else:
            self.app.call_from_thread(self._failed, "cancelled")

    def action_cancel(self) -> None:
        if self._fitting:
            self._cancel.set()

    def _failed(self, message: str) -> None:
        self._fitting = False
        self.query_one("#fit-progress", ProgressBar).display = False
        self._status(message, error=True)

    def _done(self, view: FitView) -> None:
        from quadtank_tui.core.identify.report import phase

        self._fitting = False
        self.view = view
        self.element_index = 0
        ident = view.ident
        fits = "  ".join(f"{o} {f:.1f} %" for o, f in ident.fit_percent.items())
        self._status(f"{ident.method}: fit on the validation half {fits}; phase {phase(ident)}.",
                     keys="  e: next element  v: residuals/coherence/gain  k: keep  d: design")
        self._table()
        self._draw()

    # --- views --------------------------------------------------------------------

    def _status(self, text: str, *, error: bool = False, keys: str = "") -> None:
        """The status line: `text` as it is (it quotes file names and what was
        wrong in a file, never read as markup), red for an error; then `keys`, the
        keys that follow, if they fit the line (they are the footer's too: a result
        wrapped onto a second line at 120 columns)."""
        line = self.query_one("#identify-status", Static)
        room = (line.content_size.width or self.app.size.width - 2)
        if keys and len(text) + len(keys) <= room:
            text += keys
        line.update(Content.styled(text, "red") if error else Content(text))

    def _table(self) -> None:
        from quadtank_tui.core.identify.compare import physical_time_constants
        from quadtank_tui.core.identify.report import zero_text
        from quadtank_tui.core.identify.system import time_constants

        t = self.query_one("#compare", DataTable)
        if self.method == "physical":
            t.clear(columns=True)
            if self.physical is not None:
                t.add_columns("constant", "fitted", "±", ".par", "unit")
                for row in fitui.constant_rows(self.physical):
                    t.add_row(*row)
                t.border_subtitle = f"{self.physical.start.kind}: the .par in use"
            self.query_one("#zeros", Static).update("")
            return
        if self.view is None:
            t.clear(columns=True)
            return
        ident, cmp = self.view.ident, self.view.comparison
        t.clear(columns=True)
        t.add_columns("G", "gain", "phys", "T (s)", "phys T", "fit %")
        gains = ident.system.static_gains
        for r, o in enumerate(ident.outputs):
            for c, i in enumerate(ident.inputs):
                e = ident.elements[(o, i)]
                tid = ", ".join(f"{x:.0f}" for x in time_constants(e.tf))
                if cmp is not None:
                    phys = f"{cmp.physical.static_gains[int(o[1]) - 1, int(i[1]) - 1]:.3f}"
                    tph = ", ".join(f"{x:.0f}" for x in physical_time_constants(cmp.physical, o, i))
                else:
                    phys = tph = "-"
                t.add_row(f"G{o[1:]}{i[1:]}", f"{gains[r, c]:.3f}", phys, tid, tph, f"{e.fit_percent:.1f}")
        from quadtank_tui.core.identify.report import phase

        pz = f" | {zero_text(cmp.physical.zeros)}" if cmp is not None else ""
        pp = f" | {cmp.physical.phase}" if cmp is not None else ""
        self.query_one("#zeros", Static).update(
            f"Zeros {zero_text(ident.system.zeros)}{pz}\nPhase {phase(ident)}{pp}")
        t.border_subtitle = f"physical: {self.view.physical}"

    def _element(self) -> tuple[FitView, tuple[str, str], Element] | None:
        """The fit, and the element of it on show; None before the first fit."""
        if self.view is None:
            return None
        keys = list(self.view.ident.elements)
        key = keys[self.element_index % len(keys)]
        return self.view, key, self.view.ident.elements[key]

    def _draw(self) -> None:
        self._drawn = self._draw
        top = self.query_one("#outputs", PlotView)
        low = self.query_one("#lower", PlotView)
        for plot in (top, low):
            plot.figure.reset()
        if self.method == "physical" and self.physical is not None:
            self._draw_physical(top, low, self.physical)
            return
        shown = self._element()
        if shown is None:
            top.border_title = "Measured and model output"
            low.border_title = "Residual autocorrelation"
            top.figure.note = "no fit yet"
        else:
            view, key, e = shown
            dark, no_color = self.app.current_theme.dark, self.app.no_color
            h = view.ident.h
            t = np.arange(len(e.y)) * h
            name = f"G{key[0][1:]}{key[1][1:]}"
            # the model over the measurement: where they meet, the cells take both colours
            meas_st, model_st = kit.styles([Series(key[0], BLUE), Series("model", RED)],
                                           dark=dark, no_color=no_color)
            for st, y in ((meas_st, e.y), (model_st, e.ym)):
                kit.draw(top.figure, t, y, st)
            both = np.concatenate([e.y, e.ym])
            kit.axes(top.figure, (0.0, float(t[-1])), (float(np.nanmin(both)), float(np.nanmax(both))),
                     top.content_size.width, top.content_size.height, xlabel="t (s)")
            if e.split:
                kit.vline(top.figure, float(t[e.split]), GREY, dark=dark, no_color=no_color)
            top.border_title = kit.legend([meas_st, model_st], f"{name}: ") + Content(
                f"  fit {e.fit_percent:.1f} % past the line")
            width, height = low.content_size.width, low.content_size.height
            if self.lower == "residuals":
                band_style, r_style = kit.styles([Series("99 % band", GREY, dotted=True),
                                                  Series("residual autocorrelation", BLUE)],
                                                 dark=dark, no_color=no_color)
                low.border_title = kit.legend([r_style, band_style], "Validation: ")
                if key in view.residuals:
                    lags, r, band = view.residuals[key]
                    for sign in (1, -1):
                        kit.draw(low.figure, lags, np.full(len(lags), sign * band), band_style)
                    # a stem per lag: lags are whole numbers, a line between them means nothing
                    gaps = np.full(len(lags), np.nan)
                    kit.draw(low.figure, np.column_stack([lags, lags, gaps]).ravel(),
                             np.column_stack([np.zeros(len(r)), r, gaps]).ravel(), r_style)
                    kit.axes(low.figure, (float(lags[0]) - 0.5, float(lags[-1]) + 0.5),
                             (min(-band, float(r.min())), max(band, float(r.max()))), width, height,
                             whole_x=True, xlabel="lag (samples)")
            elif self.lower == "frequency":
                w, est, mod = view.frequency[key]
                drawn = kit.styles([Series("spectral estimate", BLUE), Series("model", RED)],
                                   dark=dark, no_color=no_color)
                lw = np.log10(w)
                for st, g in zip(drawn, (est, mod)):
                    kit.draw(low.figure, lw, np.log10(g), st)
                both = np.log10(np.concatenate([est, mod]))
                kit.axes(low.figure, (float(lw.min()), float(lw.max())),
                         (float(np.nanmin(both)), float(np.nanmax(both))), width, height,
                         xlabel="log10 ω (rad/s)")
                low.border_title = kit.legend(drawn, f"log10 |{name}(iω)|: ")
            else:
                f, c = view.coherence[key]
                keep = f <= 0.1  # the thesis's range: a linear model holds up to 0.05-0.1 Hz
                (st,) = kit.styles([Series(f"coherence {key[1]} -> {key[0]}", BLUE)], dark=dark,
                                   no_color=no_color)
                kit.draw(low.figure, f[keep], c[keep], st)
                kit.axes(low.figure, (0.0, 0.1), (0.0, 1.0), width, height, xlabel="f (Hz)")
                low.border_title = kit.legend([st]) + " (Hamming window, 720 points)"
        top.refresh()
        low.refresh()

    def _draw_physical(self, top: PlotView, low: PlotView, view: fitui.PhysicalView) -> None:
        """The measured and simulated sensor on the held-out log, and their difference."""
        name, t, y, ym, where = fitui.overlay(view, self.element_index)
        dark, no_color = self.app.current_theme.dark, self.app.no_color
        drawn = kit.styles([Series(name, BLUE), Series("model", RED)], dark=dark, no_color=no_color)
        for st, v in zip(drawn, (y, ym)):  # the model last, over the measurement
            kit.draw(top.figure, t, v, st)
        both = np.concatenate([y, ym])
        kit.axes(top.figure, (0.0, float(t[-1])), (float(both.min()), float(both.max())), top.content_size.width,
                 top.content_size.height, xlabel="t (s)")
        top.border_title = kit.legend(drawn, f"{where}, V: ")
        (st,) = kit.styles([Series(f"{name} measured - model", BLUE)], dark=dark, no_color=no_color)
        r = y - ym
        kit.draw(low.figure, t, r, st)
        kit.axes(low.figure, (0.0, float(t[-1])), (float(r.min()), float(r.max())), low.content_size.width,
                 low.content_size.height,
                 xlabel="t (s)")
        low.border_title = kit.legend([st], "Output error, V: ")
        top.refresh()
        low.refresh()

    # --- keep -------------------------------------------------------------------------

    def _save_physical(self, view: fitui.PhysicalView) -> None:
        """NAME.par next to the first fitted log, of the kind of the .par in use; an
        existing file only on a second `k` (the status asks)."""
        from datetime import datetime

        from quadtank_tui.files.par import format_par

        target = fitui.par_target(view)
        if target.exists() and self._overwrite != target:
            self._overwrite = target
            self._status(f"{target} exists: k again overwrites it, any other key keeps it.", error=True)
            return
        self._overwrite = None
        try:
            path = fitui.save_par(view, format_par(self._params(), datetime.now()), target)
        except (OSError, ValueError) as exc:
            self._status(f"Cannot save the .par: {exc}", error=True)
            return
        self._status(f"Fitted constants saved in {path} ({view.fit.plant.kind})")
        self.notify(f"Saved {path}", markup=False)

    def on_key(self, event: object) -> None:
        """Any key but `k` withdraws an overwrite the status asked about."""
        if getattr(event, "key", None) != "k":
            self._overwrite = None

    def action_keep(self) -> None:
        from quadtank_tui.files.model import from_identification, model_path, write_model

        if self.method == "physical":
            if self.physical is None:
                self._status("Nothing to save yet: fit first (f).", error=True)
            else:
                self._save_physical(self.physical)
            return
        if self.view is None:
            self._status("Nothing to keep yet: fit first (f).", error=True)
            return
        ident = self.view.ident
        try:
            path = write_model(model_path(ident.records[0]), from_identification(ident))
        except OSError as exc:
            self._status(f"Cannot save the model: {exc}", error=True)
            return
        self._status(f"Model kept in {path}")
        self.notify(f"Model saved to {path}", markup=False)

    def action_export_figure(self) -> None:
        """Every element's validation, residuals and coherence, drawn in a worker."""
        from quadtank_tui.ui.figure_export import export, identification_builder

        if self.view is None:
            self._status("Nothing to draw yet: fit first (f).", error=True)
            return
        ident = self.view.ident
        first = Path(ident.records[0])
        export(self, first.parent, f"{first.stem}.{ident.method}", identification_builder(ident, self._params()))

    # --- design -----------------------------------------------------------------------

    def action_design(self) -> None:
        """The Design screen with the fitted G11 for loop 1 and G22 for loop 2."""
        from quadtank_tui.files.model import from_identification
        from quadtank_tui.ui.screens.design import DesignScreen

        if self.view is None:
            self._status("Nothing to design on yet: fit first (f).", error=True)
            return
        if self.engine is None:
            self._status("No process to design for (open Identify from Main).", error=True)
            return
        ident = self.view.ident
        G = from_identification(ident).matrix_2x2()
        if G[0][0] is None or G[1][1] is None:
            self._status("The Design screen needs G11 and G22: fit logs in which u1 and u2 move.", error=True)
            return
        name = f"the identified model ({ident.method}, {', '.join(Path(r).name for r in ident.records)})"
        self.app.push_screen(DesignScreen(self.engine, identified=G, identified_name=name))
