"""The input signal window (thesis Figure 30) and the Plot type window (Figure 35)."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import Label, OptionList
from textual.widgets.option_list import Option

from quadtank_tui.core.parameters import REFERENCE_SECTIONS, Parameters
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.files.names import PLOT_TYPES
from quadtank_tui.ui.labels import channel_label
from quadtank_tui.ui.values import fmt
from quadtank_tui.ui.windows.base import Commands, Field, ParamWindow, Window
from quadtank_tui.ui.windows.wave import period_unit


class InputSignalWindow(ParamWindow):
    """Mean, amplitude, period and on/off of one generator; the wave type is shown
    but changed on the Setup screen.  A typed mean is a step."""

    def __init__(self, channel: int, control: str, params: Parameters, defaults: Parameters, *,
                 focus_mean: bool = True, opener: str | None = None) -> None:
        sec = REFERENCE_SECTIONS[channel - 1]
        wave = fmt(params.get(f"{sec}.Wave"))
        fields = (
            Field(f"{sec}.Mean", "Mean", "0..1 (a step)"),
            Field(f"{sec}.Amplitude", "Amplitude"),
            Field(f"{sec}.Period", "Period", period_unit(wave)),
            Field(f"{sec}.On", "Wave on", flag=True),
        )
        super().__init__(f"Input {channel_label(channel, control)} - {wave} wave", params, defaults,
                         fields, opener=opener)
        self.wave = wave

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        yield Label(f"Wave type {self.wave}: changed on the Setup screen.", classes="hint")


class PlotTypeWindow(Window[Commands]):
    """Choose what one trend shows.  The other trend's type is listed greyed and
    cannot be chosen (thesis Figure 35)."""

    BINDINGS = [Binding(str(n + 1), f"choose({n})", show=False) for n in range(len(PLOT_TYPES))]

    def __init__(self, which: str, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        super().__init__(f"Plot type - {which} trend", opener=opener)
        self.key = "PLOTS.Upper" if which == "upper" else "PLOTS.Lower"
        other = "PLOTS.Lower" if which == "upper" else "PLOTS.Upper"
        self.current = params.get(self.key)
        self.other = params.get(other)
        self.default = defaults.get(self.key)

    def compose_body(self) -> ComposeResult:
        options = []
        for n, t in enumerate(PLOT_TYPES):
            note = "  (other trend)" if t == self.other else ("  (default)" if t == self.default else "")
            options.append(Option(f"{n + 1}  {t}{note}", id=f"plot-{n}", disabled=t == self.other))
        yield OptionList(*options, id="plot-types")
        yield Label("Enter chooses; Esc keeps the current type.", classes="hint")

    def on_mount(self) -> None:
        ol = self.query_one(OptionList)
        ol.highlighted = PLOT_TYPES.index(self.current)
        ol.focus()

    def action_choose(self, n: int) -> None:
        if PLOT_TYPES[n] != self.other:
            self._choose(PLOT_TYPES[n])

    def _choose(self, plot_type: str) -> None:
        self.dismiss(() if plot_type == self.current else (SetParams({self.key: plot_type}),))

    @on(OptionList.OptionSelected)
    def _selected(self, event: OptionList.OptionSelected) -> None:
        self._choose(PLOT_TYPES[event.option_index])
