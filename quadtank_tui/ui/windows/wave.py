"""The Setup screen's reference configuration window (thesis 5.4; S2): one
channel's wave type - Square, Sine or PRBS - and its parameters.

Period means seconds for Square and Sine and the minimum number of samples between
changes for PRBS, so its unit follows the chosen type, and the seed is used only by
PRBS.  The parameter model validates the type, the period and the sampling time
together: a period too short is refused with the shortest allowed value, where the
original silently produced a constant.
"""

from __future__ import annotations

from typing import Any

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Input, Label, RadioButton, RadioSet

from quadtank_tui.core.parameters import REFERENCE_SECTIONS, Parameters
from quadtank_tui.core.controllers.signals import Wave
from quadtank_tui.ui.windows.base import Field, ParamWindow

WAVES = tuple(w.value for w in Wave)


class Radio(RadioButton):
    """A radio button that shows its dot only when chosen: Textual tells the
    states apart by colour alone, which an SSH terminal's scheme may hide."""

    @property
    def BUTTON_INNER(self) -> str:  # type: ignore[override]  # Textual's is a class constant
        return "●" if self.value else " "


def period_unit(wave: str) -> str:
    return "samples" if wave == Wave.PRBS.value else "s"


class WaveWindow(ParamWindow):
    """Wave type and mean, amplitude, period, seed, on/off of channel 1 or 2."""

    BINDINGS = [Binding("ctrl+t", "next_wave", "Wave type")]

    def __init__(self, channel: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        sec = REFERENCE_SECTIONS[channel - 1]
        self.section = sec
        self.wave_key = f"{sec}.Wave"
        self.wave: str = params.get(self.wave_key).value
        fields = (
            Field(f"{sec}.Mean", "Mean", "0..1"),
            Field(f"{sec}.Amplitude", "Amplitude", "0..1"),
            Field(f"{sec}.Period", "Period", period_unit(self.wave)),
            Field(f"{sec}.Seed", "PRBS seed"),
            Field(f"{sec}.On", "Wave on", flag=True),
        )
        super().__init__(f"Reference {channel} - wave", params, defaults, fields, opener=opener)
        self.channel = channel

    def compose_body(self) -> ComposeResult:
        with Horizontal(classes="field wave-row", id="row-wave"):
            yield Label("Wave type", classes="label")
            with RadioSet(id="wave"):
                for w in WAVES:
                    yield Radio(w, value=w == self.wave, id=f"wave-{w}")
        yield from super().compose_body()
        yield Label("Period: s for Square and Sine; samples between changes for PRBS.", classes="hint")

    def on_mount(self) -> None:
        super().on_mount()
        self._wave_chosen(self.wave)

    # --- the wave type -------------------------------------------------------------------

    def _wave_chosen(self, wave: str) -> None:
        self.wave = wave
        i_period = [f.key for f in self.fields].index(f"{self.section}.Period")
        self.query_one(f"#row-{i_period} .unit", Label).update(period_unit(wave))
        i_seed = [f.key for f in self.fields].index(f"{self.section}.Seed")
        prbs = wave == Wave.PRBS.value
        self.query_one(f"#row-{i_seed}").set_class(not prbs, "-unused")
        self.query_one(f"#f-{i_seed}", Input).disabled = not prbs
        self.query_one("#row-wave").set_class(wave != self.defaults.get(self.wave_key).value, "-modified")

    @on(RadioSet.Changed, "#wave")
    def _radio(self, event: RadioSet.Changed) -> None:
        self._wave_chosen(WAVES[event.index])

    def action_next_wave(self) -> None:
        nxt = WAVES[(WAVES.index(self.wave) + 1) % len(WAVES)]
        self.query_one(f"#wave-{nxt}", Radio).value = True

    # --- values ---------------------------------------------------------------------------

    def extra_values(self) -> dict[str, Any]:
        """The wave type, validated with the fields (the period's meaning depends
        on it)."""
        return {self.wave_key: self.wave}

    def action_default(self) -> None:
        super().action_default()
        self.query_one(f"#wave-{self.defaults.get(self.wave_key).value}", Radio).value = True
