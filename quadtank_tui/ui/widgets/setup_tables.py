"""The Setup screen's tables: references, controller elements with the PID extras,
and the simulated tanks (S2-S4, S6).

Each row is one object the user can open (a channel, an element, a tank): arrow
keys or the mouse choose it, Enter or a click opens its window.  The tables render
the parameters they are given (attributes down) and ask the screen to open a
window by posting the same action a key runs (messages up); a value that differs
from its default is shown dim italic, as the original drew it gray.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from rich.text import Text
from textual.reactive import reactive
from textual.widgets import DataTable

from quadtank_tui.core.parameters import CONTROLLER_SECTIONS, REFERENCE_SECTIONS, Parameters
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.values import fmt
from quadtank_tui.ui.widgets.controller_box import element_used

MODIFIED = "italic dim"


@dataclass(frozen=True)
class Column:
    """A column: its header and, for a row, the `.par` key it shows (None: blank)."""

    header: str
    key: Callable[[int], str | None]
    fmt: Callable[[object], str] = fmt


class ParamTable(DataTable[Text]):
    """Rows of parameters, one row per object; `params`/`defaults` set by the screen."""

    params: reactive[Parameters | None] = reactive(None, always_update=True)

    #: Row labels, and the action each row's Enter asks for ("{n}" is the row number).
    ROWS: tuple[str, ...] = ()
    ACTION = ""
    #: Added to the row number in ACTION (tanks and channels count from 1).
    FIRST = 0
    COLUMNS: tuple[Column, ...] = ()

    def __init__(self, defaults: Parameters, **kwargs: Any) -> None:
        super().__init__(cursor_type="row", zebra_stripes=False, show_cursor=True, **kwargs)
        self.defaults = defaults

    def on_mount(self) -> None:
        # Not through watch_params: Textual's is_mounted turns True only after on_mount.
        if self.params is not None:
            self.show(self.params)

    def columns_for(self, params: Parameters) -> tuple[Column, ...]:
        """The columns for these parameters (the controller's follow its family)."""
        return self.COLUMNS

    def _build(self, columns: tuple[Column, ...]) -> None:
        row = self.cursor_row
        self.clear(columns=True)
        self.add_column("", key="row")
        for c in columns:
            self.add_column(c.header, key=c.header)
        for n, label in enumerate(self.ROWS):
            self.add_row(Text(label, style="bold"), *(Text("") for _ in columns), key=str(n))
        self.move_cursor(row=row)

    def cell(self, params: Parameters, row: int, column: Column) -> Text:
        key = column.key(row)
        if key is None:
            return Text("-", style="dim")
        text = column.fmt(params.get(key))
        return Text(text, style=MODIFIED if params.is_modified(key, self.defaults) else "")

    def watch_params(self, params: Parameters | None) -> None:
        if params is not None and self.is_mounted:
            self.show(params)

    def show(self, params: Parameters) -> None:
        """The rows for `params`."""
        columns = self.columns_for(params)
        if [c.header for c in columns] != [str(c.label) for c in list(self.columns.values())[1:]]:
            self._build(columns)
        for n in range(len(self.ROWS)):
            for c in columns:
                self.update_cell(str(n), c.header, self.cell(params, n, c), update_width=True)
            self.update_cell(str(n), "row", self.row_label(params, n), update_width=True)

    def row_label(self, params: Parameters, row: int) -> Text:
        return Text(self.ROWS[row], style="bold")

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        event.stop()
        self.post_message(ActionRequested(self.ACTION.format(n=event.cursor_row + self.FIRST)))


def _wave(value: object) -> str:
    return str(getattr(value, "value", value))


class ReferenceTable(ParamTable):
    """Both generators: wave type and its parameters (u1/u2 in Manual, ref1/ref2 in
    Automatic, as the labels on Main)."""

    ROWS = ("1", "2")
    ACTION = "reference({n})"
    FIRST = 1
    COLUMNS = (
        Column("Wave", lambda n: f"{REFERENCE_SECTIONS[n]}.Wave", _wave),
        Column("Mean", lambda n: f"{REFERENCE_SECTIONS[n]}.Mean"),
        Column("Ampl.", lambda n: f"{REFERENCE_SECTIONS[n]}.Amplitude"),
        Column("Period", lambda n: f"{REFERENCE_SECTIONS[n]}.Period"),
        Column("Seed", lambda n: f"{REFERENCE_SECTIONS[n]}.Seed"),
        Column("On", lambda n: f"{REFERENCE_SECTIONS[n]}.On"),
    )

    def row_label(self, params: Parameters, row: int) -> Text:
        name = "u" if params.control.mode.value == "Manual" else "ref"
        return Text(f"{name}{row + 1}", style="bold")

    def cell(self, params: Parameters, row: int, column: Column) -> Text:
        text = super().cell(params, row, column)
        if column.header == "Period":
            prbs = params.references[row].wave.value == "PRBS"
            text.append(" smp" if prbs else " s", style="dim")
        return text


def _pid(name: str) -> Callable[[int], str]:
    return lambda n: f"{CONTROLLER_SECTIONS[n]}.{name}"


class ControllerTable(ParamTable):
    """The four elements with the parameters of the family in force: every PID
    parameter, extras included, or the General transfer functions' coefficients.
    The elements a decentralized structure does not use are dimmed."""

    ROWS = ("11", "12", "21", "22")
    ACTION = "element({n})"
    COLUMNS = tuple(Column(name, _pid(name)) for name in ("K", "Ti", "Td", "I", "D", "N", "Tr", "a", "b"))
    GENERAL = tuple(Column(name, _pid(name)) for name in ("Degree", "s0", "s1", "s2", "s3", "s4", "r1", "r2", "r3", "r4"))

    def columns_for(self, params: Parameters) -> tuple[Column, ...]:
        return self.COLUMNS if params.control.family.value == "PID" else self.GENERAL

    def row_label(self, params: Parameters, row: int) -> Text:
        return Text(self.ROWS[row], style="bold" if element_used(params, row) else "dim strike")


def _tank(name: str, tanks: tuple[int, ...] = (1, 2, 3, 4)) -> Callable[[int], str | None]:
    return lambda n: f"SIMULATION.{name}{n + 1}" if n + 1 in tanks else None


class ProcessTable(ParamTable):
    """The simulated tanks as configured: operating point, diameter, time constant,
    and the valve of the two lower tanks."""

    ROWS = ("Tank 1", "Tank 2", "Tank 3", "Tank 4")
    ACTION = "tank({n})"
    FIRST = 1
    COLUMNS = (
        Column("Op.Pt", _tank("OpPoint"), lambda v: f"{v:.3f}"),
        Column("Diam cm", _tank("Diameter"), lambda v: f"{v:.2f}"),
        Column("T s", _tank("TimeConst"), lambda v: f"{v:.2f}"),
        Column("γ", _tank("Valve", (1, 2)), lambda v: f"{v:.2f}"),
    )

    def show(self, params: Parameters) -> None:
        if params.process is None:
            super().show(params)
            return
        # another plant (a PLANT section): its constants and operating levels (Enter
        # opens the plant window that edits them; core.plants.spec)
        plant = params.process_plant()
        rows = [(f"{s.name} op.", f"{x:.4g} {s.unit}") for s, x in zip(plant.states, params.process_levels())]
        rows += [(name, f"{value:.6g}") for name, value in plant.values().items()]
        if rows == getattr(self, "_plant_rows", None) and len(self.columns) == 4:
            return  # unchanged: keep the cursor (the screen refreshes 20 times a second)
        self._plant_rows = rows
        self.clear(columns=True)
        self.add_column(plant.kind, key="row")  # two constants a row: the analysis stays in view
        for key in ("v1", "n2", "v2"):
            self.add_column("", key=key)
        for n in range(0, len(rows), 2):
            (a, va), (b, vb) = rows[n], rows[n + 1] if n + 1 < len(rows) else ("", "")
            self.add_row(Text(a, style="bold"), Text(va), Text(b, style="bold"), Text(vb), key=str(n // 2))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        # Textual also runs ParamTable's handler (every class in the MRO): for another
        # plant, whose values have one window, ask for it here and stop that one.
        if self.params is not None and self.params.process is not None:
            event.stop()
            event.prevent_default()
            self.post_message(ActionRequested("plant"))
