"""The Setup screen's Tank window (thesis 5.4, Figure 39; S4).

Operating point, diameter, time constant and, for the lower tanks, the valve
position gamma.  The values are linked through the tank's hidden outlet area
(``core.setup_relations``): typing a diameter or an operating point recomputes the
time constant at once, typing a time constant moves the outlet, which the window
shows so the user sees why.  Below the fields the analysis of the setting being
edited (time constants, zeros, phase) follows every keystroke, so moving
gamma1 + gamma2 across 1 shows the zero crossing into the right half-plane before
anything is set.  Set sends the changed SIMULATION keys; nothing reaches the
engine before.
"""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import Input, Label, Static

from quadtank_tui.core.parameters import Parameters, SimulationSettings
from quadtank_tui.core.setup_relations import diff, edit_by_key, outlet, tank_keys, tank_setup
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.ui.values import fmt, parse_number
from quadtank_tui.ui.widgets.analysis_panel import AnalysisPanel
from quadtank_tui.ui.windows.base import Commands, Window, field_row, set_default_cancel

#: Label and unit of each tank value, by the key's name without the tank number.
ROWS = {
    "OpPoint": ("Op. Point", "0..1 of 20 cm"),
    "Diameter": ("Diameter", "cm"),
    "TimeConst": ("Time Const.", "s"),
    "Valve": ("Valve Pos.", "γ, 0..1 to the lower tank"),
}


def _name(key: str) -> str:
    """'SIMULATION.Diameter1' -> 'Diameter'."""
    return key.split(".", 1)[1].rstrip("1234")


class TankSetupWindow(Window[Commands]):
    """Edit one tank of the simulated process with its linked values."""

    BINDINGS = [Binding("enter", "set", "Set"), Binding("ctrl+r", "default", "Default")]

    def __init__(self, tank: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        super().__init__(f"Tank {tank}", opener=opener)
        self.tank = tank
        self.params = params
        self.defaults = defaults
        self.keys = tank_keys(tank)
        #: The setting as edited so far (exact values; the fields show them rounded).
        self.working: SimulationSettings = params.simulation
        #: Why a field's text is refused, by field name (the analysis waits for them).
        self.refused: dict[str, str] = {}

    # --- layout -------------------------------------------------------------------------

    def compose_body(self) -> ComposeResult:
        for key in self.keys:
            name = _name(key)
            label, unit = ROWS[name]
            field = Input(fmt(self.params.get(key)), id=f"f-{name}", compact=True, select_on_focus=True)
            yield from field_row(f"row-{name}", label, field, unit, f"e-{name}")
        yield Label("", id="outlet", classes="hint")
        yield AnalysisPanel(id="tank-analysis")

    def compose_buttons(self) -> ComposeResult:
        yield from set_default_cancel()

    def on_mount(self) -> None:
        self._show()

    # --- the working setting -------------------------------------------------------------

    def value(self, key: str) -> float:
        return tank_setup(self.working, self.tank).values()[key]

    def _show(self, typing: str | None = None) -> None:
        """Fields, marks, the outlet line and the analysis from `working`; the field
        being typed in (`typing`) keeps its text."""
        for key in self.keys:
            name = _name(key)
            if key != typing and not self._holds(key):
                self.query_one(f"#f-{name}", Input).value = fmt(self.value(key))
                self.refused.pop(name, None)
            self.query_one(f"#row-{name}").set_class(self.value(key) != self.defaults.get(key), "-modified")
        a = outlet(self.working, self.tank)
        a_used = outlet(self.params.simulation, self.tank)
        note = "held fixed" if abs(a - a_used) <= 1e-9 * a_used else f"was {a_used:.4f}"
        self.query_one("#outlet", Label).update(f"Outlet area a{self.tank} = {a:.4f} cm^2 ({note})")
        self._analyse()

    def _analyse(self) -> None:
        """The analysis of the working setting, or why there is none."""
        panel = self.query_one(AnalysisPanel)
        if self.refused:
            name, reason = next(iter(self.refused.items()))
            text = self.query_one(f"#f-{name}", Input).value
            panel.refuse(f"{ROWS[name][0]} {text} is refused ({reason})")
        else:
            panel.params = self.params.with_values(diff(self.params.simulation, self.working))

    def _holds(self, key: str) -> bool:
        """Whether a field's text stands for the working value: as shown (rounded
        to 6 digits) or typed equal to it ("5." for 5)."""
        text = self.query_one(f"#f-{_name(key)}", Input).value
        if text == fmt(self.value(key)):
            return True
        try:
            return parse_number(key, text) == self.value(key)
        except ParameterError:
            return False

    @on(Input.Changed)
    def _typed(self, event: Input.Changed) -> None:
        name = (event.input.id or "")[2:]
        key = next(k for k in self.keys if _name(k) == name)
        error = self.query_one(f"#e-{name}", Static)
        error.update("")
        self.refused.pop(name, None)
        if self._holds(key):  # shown by _show, or typed back as it was
            self._analyse()
            return
        try:
            self.working = edit_by_key(self.working, key, parse_number(key, event.value)).after
        except ParameterError as exc:
            error.update(exc.reason)
            self.refused[name] = exc.reason
            self._analyse()
            return
        self._show(typing=key)

    # --- actions ---------------------------------------------------------------------------

    def action_set(self) -> None:
        if not all(self._holds(k) for k in self.keys):
            self.show_message("Correct the marked value first (Esc cancels).")
            return
        changes = diff(self.params.simulation, self.working)
        self.dismiss((SetParams(changes),) if changes else ())

    def action_default(self) -> None:
        self.working = self.params.with_values({k: self.defaults.get(k) for k in self.keys}).simulation
        self.refused.clear()
        for key in self.keys:
            self.query_one(f"#e-{_name(key)}", Static).update("")
        self._show()

    @on(Input.Submitted)
    def _submitted(self) -> None:
        self.action_set()
