"""The Tank and Pump windows of the process image (thesis Figures 33-34).

They show live values, so the screen hands them each new snapshot (attributes
down).  In Simul the Tank window adds water: the amount entered is poured into the
chosen tank as a disturbance (a negative amount takes water out).
"""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Input, Label, Static

from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import AddWater
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.values import fixed, fmt, parse_number
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import LiveWindow, show_live

_TANK_ROWS = (("Op. Point", "OpPoint"), ("Diameter", "Diameter"), ("Time Const.", "TimeConst"))


class TankTable(Static, can_focus=True):
    """The table of tanks (or pumps); with the focus on it 1-4 and up/down choose
    one without typing anywhere."""


def water_problem(amount: float, tank: int, level: float, full: float) -> str | None:
    """Why `amount` (normalized) cannot go into `tank` at `level` (None if it can):
    no more than the free volume up to `full`, no more out than is there."""
    if amount > 0 and amount > full - level + 1e-9:
        return f"tank {tank} has room for {max(0.0, full - level):.2f} (level {level:.2f} of {full:.2f})"
    if amount < 0 and -amount > level + 1e-9:
        return f"tank {tank} holds only {max(0.0, level):.2f}"
    return None


class _LiveWindow(LiveWindow):
    def __init__(self, title: str, snapshot: Snapshot, defaults: Parameters, selected: int, *,
                 count: int, opener: str | None = None) -> None:
        super().__init__(title, snapshot, opener=opener)
        self.defaults = defaults
        self.selected = selected
        self.count = count
        for n in range(1, count + 1):
            self._bindings.bind(str(n), f"select({n})", show=False)
        # Digits go into the amount field while it has the focus; up/down do not.
        self._bindings.bind("up", "cycle(-1)", show=False)
        self._bindings.bind("down", "cycle(1)", show=False)

    def compose_body(self) -> ComposeResult:
        yield TankTable(id="table")

    def on_mount(self) -> None:
        self.query_one(TankTable).focus()

    def action_select(self, n: int) -> None:
        self.selected = n
        self.watch_snapshot(self.snapshot)

    def action_cycle(self, step: int) -> None:
        self.action_select((self.selected - 1 + step) % self.count + 1)

    def show(self, snapshot: Snapshot) -> None:
        show_live(self.query_one("#table", Static), self.table(snapshot))

    def table(self, snapshot: Snapshot) -> str:
        raise NotImplementedError

    def _header(self, name: str) -> str:
        cells = []
        for n in range(1, self.count + 1):
            cell = f"{name} {n}".rjust(9)
            cells.append(f"[reverse]{cell}[/]" if n == self.selected else cell)
        return " " * 12 + "".join(cells)


class TankWindow(_LiveWindow):
    """Op. point, diameter, time constant and height of the four tanks; the
    selected one (1-4) is highlighted and receives the water Set adds."""

    BINDINGS = [Binding("enter", "set", "Add", show=False)]

    def __init__(self, snapshot: Snapshot, defaults: Parameters, tank: int = 1, *,
                 opener: str | None = None) -> None:
        super().__init__("Tanks", snapshot, defaults, tank, count=4, opener=opener)

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        with Horizontal(classes="field", id="add-row"):
            yield Label("Add water", classes="label")
            yield Input("", id="amount", placeholder="e.g. 0.1", compact=True)
            yield Label("", id="add-unit", classes="unit")
            yield Static("", classes="error", id="amount-error", markup=False)
        yield Label("1-4 or up/down choose the tank, then type the amount; "
                    "heights are fractions of the sensor range.", classes="hint")

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Set", id="set", variant="primary")
        yield KeyButton("Cancel", id="cancel")

    def on_mount(self) -> None:
        super().on_mount()
        simul = self.snapshot is not None and self.snapshot.operation == "Simul"
        self.query_one("#amount", Input).disabled = not simul
        if not simul:
            self.query_one("#amount-error", Static).update("only in Simul")
        self._show_target()

    def action_select(self, n: int) -> None:
        """Choose tank n; its amount is typed next (a digit chooses, never types)."""
        super().action_select(n)
        self._show_target()
        amount = self.query_one("#amount", Input)
        if not amount.disabled:
            amount.focus()

    def _show_target(self) -> None:
        self.query_one("#add-unit", Label).update(f"into tank {self.selected}")

    def table(self, snapshot: Snapshot) -> str:
        p = snapshot.params
        lines = [self._header("Tank")]
        for label, key in _TANK_ROWS:
            cells = []
            for n in range(1, 5):
                k = f"SIMULATION.{key}{n}"
                text = f"{p.get(k):9.2f}"
                cells.append(f"[i dim]{text}[/]" if p.is_modified(k, self.defaults) else text)
            lines.append(f"{label:<12}" + "".join(cells))
        lines.append(f"{'Height':<12}" + "".join(f"{fixed(y):>9}" for y in snapshot.y))
        return "\n".join(lines)

    def on_input_changed(self, event: Input.Changed) -> None:
        self.query_one("#amount-error", Static).update("")

    def action_set(self) -> None:
        text = self.query_one("#amount", Input).value
        if not text.strip():
            self.dismiss(())
            return
        try:
            amount = parse_number("amount", text)
        except ParameterError as exc:
            self.query_one("#amount-error", Static).update(exc.reason)
            return
        snap = self.snapshot
        if snap is not None:
            sensors = snap.params.process_plant().outputs  # the plant in use
            if self.selected > len(sensors):
                self.query_one("#amount-error", Static).update(f"the plant has no tank {self.selected}")
                return
            full = sensors[self.selected - 1].hi / FULL_SCALE_V
            problem = water_problem(amount, self.selected, snap.y[self.selected - 1], full)
            if problem is not None:
                self.query_one("#amount-error", Static).update(problem)
                return
        self.dismiss((AddWater(self.selected, amount),) if amount else ())

    @on(Input.Submitted)
    def _submitted(self) -> None:
        self.action_set()


class PumpWindow(_LiveWindow):
    """Both pumps' inputs (normalized and volts) and where their water goes: the
    valve sends gamma of it to the lower tank, the rest to the opposite upper tank.
    Nothing to set here (as the original's Figure 34)."""

    def __init__(self, snapshot: Snapshot, defaults: Parameters, pump: int = 1, *,
                 opener: str | None = None) -> None:
        super().__init__("Pumps", snapshot, defaults, pump, count=2, opener=opener)

    def compose_buttons(self) -> ComposeResult:
        yield KeyButton("Close", id="cancel")

    def table(self, snapshot: Snapshot) -> str:
        p = snapshot.params
        u = snapshot.u
        g = (p.get("SIMULATION.Valve1"), p.get("SIMULATION.Valve2"))
        rows = [
            self._header("Pump"),
            f"{'Input':<12}" + "".join(f"{fixed(x):>9}" for x in u),
            f"{'Volts':<12}" + "".join(f"{fixed(FULL_SCALE_V * x, 2):>9}" for x in u),
            f"{'Valve gamma':<12}" + "".join(f"{fmt(x):>9}" for x in g),
            f"{'to tank':<12}" + f"{'1: ' + fmt(g[0]):>9}{'2: ' + fmt(g[1]):>9}",
            f"{'':<12}" + f"{'4: ' + fmt(round(1 - g[0], 6)):>9}{'3: ' + fmt(round(1 - g[1], 6)):>9}",
        ]
        return "\n".join(rows)
