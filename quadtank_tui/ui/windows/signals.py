"""The input signal window (thesis Figure 30) and the Plot type window (Figure 35)."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import Input, Label, OptionList
from textual.widgets.option_list import Option

from quadtank_tui.core.parameters import REFERENCE_SECTIONS, Parameters
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.files.names import PLOT_TYPES
from quadtank_tui.ui.labels import channel_label
from quadtank_tui.ui.values import fmt, parse_number
from quadtank_tui.ui.windows.base import Commands, Field, ParamWindow, Window
from quadtank_tui.ui.windows.wave import period_unit


def relative(text: str) -> bool:
    """Whether a typed value is a change of the value in force (`+0.1`, `-0.05`):
    it starts with a sign."""
    return text.strip()[:1] in ("+", "-")


class InputSignalWindow(ParamWindow):
    """Mean, amplitude, period and on/off of one generator; the wave type is shown
    but changed on the Setup screen.  A typed mean is a step; a signed one
    (`+0.1`, `-0.05`) steps the mean (or the amplitude) by that much from the value
    in force, as the thesis's step experiments are described."""

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
        #: The fields a signed value steps (mean, amplitude).
        self.steppable = (f"{sec}.Mean", f"{sec}.Amplitude")

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        yield Label(f"+0.1 or -0.05 steps the mean or amplitude by that much. "
                    f"Wave type {self.wave}: changed on the Setup screen.", classes="hint")

    def _typed(self, key: str) -> str:
        return self.query_one(f"#f-{[f.key for f in self.fields].index(key)}", Input).value

    def _read(self, i: int) -> object:
        key = self.fields[i].key
        if key in self.steppable and relative(text := self._typed(key)):
            # Rounded so 0.3 + 0.1 is 0.4, as typed, not 0.4000000000000001.
            return round(float(self.params.get(key)) + parse_number(key, text), 9)
        return super()._read(i)

    def _error(self, key: str, reason: str) -> None:
        """A refused step says what it was a step from."""
        if key in self.steppable and relative(text := self._typed(key)):
            try:
                delta = parse_number(key, text)
            except ParameterError:
                pass
            else:
                base = float(self.params.get(key))
                reason = f"{fmt(base)} {'+' if delta >= 0 else '-'} {fmt(abs(delta))} = " \
                         f"{fmt(round(base + delta, 9))}: {reason}"
        super()._error(key, reason)


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
