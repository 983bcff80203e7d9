"""The Faults window (B7): break the simulated process on purpose, and drive the
disturbance pumps.

A list of the fault kinds (core.faults, Simul only), the tank, pump, sensor or
valve it hits, and its value; On switches it on (replacing one of the same kind
there), Off switches it off.  The faults in force are listed from the live
snapshot.  The engine checks the fault against the plant and says why it refuses one.

Where the process has disturbance pumps (an IST rig in Active, the simulated
quadruple tank in Simul: engine.commands.SetDisturbance), two more fields hold d1
and d2 in percent of full PWM (the rig's 8-bit PWM: 100 % is 255); Enter in one of
them, or Set d, sends both.  Every safe state puts them back at 0.
"""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from quadtank_tui.core.faults import KINDS
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import SetDisturbance, SetFault
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.values import parse_number
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import Commands, Window

NAMES = tuple(KINDS)
#: What the value means, short enough for an 80-column window.
VALUES = {
    "leak": "area of the extra outlet", "clog": "fraction left open", "weak_pump": "fraction of flow left",
    "valve_drift": "gamma per s", "sensor_bias": "offset (normalized)", "sensor_drift": "offset per s",
    "sensor_noise": "standard deviation", "sensor_stuck": "(none: stuck where it reads)",
}


class FaultWindow(Window[Commands]):
    """Choose a kind, its target and value; On or Off."""

    BINDINGS = [Binding("enter", "on", "On", show=False)]

    def __init__(self, snapshot: Snapshot, *, opener: str | None = None) -> None:
        pumps = snapshot.disturbances is not None
        super().__init__("Faults (Simul) and disturbance pumps" if pumps else "Faults (Simul)", opener=opener)
        self.snapshot = snapshot
        self.kind = NAMES[0]

    def compose_body(self) -> ComposeResult:
        yield OptionList(*(Option(f"{k.replace('_', ' '):<13} {KINDS[k][0]:<7} {VALUES[k]}", id=k) for k in NAMES),
                         id="kinds")
        with Horizontal(classes="field"):
            yield Label("Target", classes="label")
            yield Input("1", id="target", compact=True)
            yield Label("", id="target-unit", classes="unit")
        with Horizontal(classes="field"):
            yield Label("Value", classes="label")
            yield Input("", id="value", placeholder="e.g. 0.02", compact=True)
        active = self.snapshot.faults or "none"
        yield Static(f"In force: {active}", id="active", classes="hint")
        duties = self.snapshot.disturbances
        if duties is not None:
            into = "into tank {}" if self.snapshot.operation == "Simul" else "on the rig"
            for i, d in enumerate(duties, start=1):
                with Horizontal(classes="field"):
                    yield Label(f"Disturb. d{i}", classes="label")
                    yield Input(f"{100 * d:.4g}", id=f"d{i}", compact=True)
                    yield Label(f"% of full PWM, {into.format(i)}", classes="unit")
        if self.snapshot.operation != "Simul":
            yield Static("Faults act on the simulation only: switch to Simul first."
                         + (" d1, d2 drive the rig's disturbance pumps." if duties is not None else ""),
                         classes="error")

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("On", id="on", variant="primary")
        yield KeyButton("Off", id="off")
        if self.snapshot.disturbances is not None:
            yield KeyButton("Set d", id="disturb")
        yield KeyButton("Cancel", id="cancel")

    def on_mount(self) -> None:
        self.query_one(OptionList).highlighted = 0
        self.query_one(OptionList).focus()
        self._show_target()

    @on(OptionList.OptionHighlighted)
    def _highlighted(self, event: OptionList.OptionHighlighted) -> None:
        self.kind = NAMES[event.option_index]
        self._show_target()

    @on(OptionList.OptionSelected)
    def _selected(self, event: OptionList.OptionSelected) -> None:
        self.kind = NAMES[event.option_index]
        self.query_one("#target", Input).focus()

    def _show_target(self) -> None:
        if self.is_mounted:
            self.query_one("#target-unit", Label).update(KINDS[self.kind][0])

    def _command(self, on: bool) -> SetFault | None:
        try:
            target = parse_number("target", self.query_one("#target", Input).value)
            text = self.query_one("#value", Input).value
            value = parse_number("value", text) if text.strip() else 0.0
        except ParameterError as exc:
            self.show_message(exc.reason)
            return None
        if target != int(target) or target < 1:
            self.show_message(f"the target is a {KINDS[self.kind][0]} number 1, 2, ...")
            return None
        return SetFault(self.kind, int(target), value, on)

    def action_on(self) -> None:
        command = self._command(True)
        if command is not None:
            self.dismiss((command,))

    @on(Input.Submitted)
    def _submitted(self, event: Input.Submitted) -> None:
        if event.input.id in ("d1", "d2"):
            self.action_disturb()
        else:
            self.action_on()

    def action_disturb(self) -> None:
        """Both disturbance pumps as typed (percent of full PWM)."""
        duties = []
        for name in ("d1", "d2"):
            try:
                value = parse_number(name, self.query_one(f"#{name}", Input).value)
            except ParameterError as exc:
                self.show_message(exc.reason)
                return
            if not 0.0 <= value <= 100.0:
                self.show_message(f"{name} is a percent of full PWM, 0..100, got {value:g}")
                return
            duties.append(value / 100.0)
        self.dismiss((SetDisturbance(duties[0], duties[1]),))

    def action_off(self) -> None:
        command = self._command(False)
        if command is not None:
            self.dismiss((command,))
