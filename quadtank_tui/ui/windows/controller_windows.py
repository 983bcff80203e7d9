"""The controller windows of the Main screen (thesis Figures 31-32): the Type
window and one element's PID or General window."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import Input, Label, OptionList
from textual.widgets.option_list import Option

from quadtank_tui.core.controllers.general import MAX_DEGREE
from quadtank_tui.core.parameters import CONTROLLER_SECTIONS, Parameters
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import ResetControllers, SetParams
from quadtank_tui.ui.labels import ELEMENT_NAMES, TYPES, type_index
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import Commands, Field, ParamWindow, Window, set_default_cancel

def element_ij(index: int) -> tuple[int, int]:
    """Element 0..3 as (i, j), 1-based, as ResetControllers wants it."""
    return (index // 2 + 1, index % 2 + 1)


class ControllerTypeWindow(Window[Commands]):
    """Choose one of the four structures (up/down or 1-4, Enter); Set sends
    CONTROL.Type and CONTROL.Structure.

    The engine keeps the controllers' states only between the two structures of
    one family (M5); the window says so, since the choice resets them otherwise.
    """

    BINDINGS = [Binding(str(n + 1), f"choose({n})", show=False) for n in range(len(TYPES))]

    def __init__(self, params: Parameters, defaults: Parameters, *, opener: str | None = None) -> None:
        super().__init__("Controller type", opener=opener)
        self.current = type_index(params)
        self.default = type_index(defaults)

    def compose_body(self) -> ComposeResult:
        options = []
        for n, (_, _, label) in enumerate(TYPES):
            note = "  (in force)" if n == self.current else ""
            note += "  (default)" if n == self.default else ""
            options.append(Option(f"{n + 1}  {label}{note}", id=f"type-{n}"))
        yield OptionList(*options, id="types")
        yield Label("States are kept only between the two structures of one family; "
                    "state feedback and MPC start from the pumps' u.", classes="hint")

    def compose_buttons(self) -> ComposeResult:
        yield from set_default_cancel()

    def on_mount(self) -> None:
        types = self.query_one(OptionList)
        types.highlighted = self.current
        types.focus()

    def action_choose(self, n: int) -> None:
        family, structure, _ = TYPES[n]
        values = {"CONTROL.Type": family.value}
        if not family.whole:
            values["CONTROL.Structure"] = structure.value
        self.dismiss(() if n == self.current else (SetParams(values),))

    def action_set(self) -> None:
        highlighted = self.query_one(OptionList).highlighted
        self.action_choose(self.current if highlighted is None else highlighted)

    def action_default(self) -> None:
        self.query_one(OptionList).highlighted = self.default

    @on(OptionList.OptionSelected)
    def _selected(self, event: OptionList.OptionSelected) -> None:
        self.action_choose(event.option_index)


class PIDWindow(ParamWindow):
    """K, Ti, Td and the I/D enables of one element, and a Reset of its states
    (N, Tr, a and b are on the Setup screen, as in the original)."""

    def __init__(self, index: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        sec = CONTROLLER_SECTIONS[index]
        fields = (
            Field(f"{sec}.K", "K", "gain"),
            Field(f"{sec}.Ti", "Ti", "s"),
            Field(f"{sec}.Td", "Td", "s"),
            Field(f"{sec}.I", "Integral", flag=True),
            Field(f"{sec}.D", "Derivative", flag=True),
        )
        super().__init__(f"Controller {ELEMENT_NAMES[index]} - PID", params, defaults, fields, opener=opener)
        self.index = index

    def compose_buttons(self) -> ComposeResult:
        yield from super().compose_buttons()
        yield KeyButton("Reset", id="reset_element")

    def action_reset_element(self) -> None:
        """Reset this element's states now (the window closes, nothing else changes)."""
        self.dismiss((ResetControllers(element_ij(self.index)),))


class GeneralWindow(ParamWindow):
    """Degree 0..4 and the transfer function's coefficients,
    (s0 s^n + ... + sn) / (s^n + r1 s^(n-1) + ... + rn); the coefficients the
    degree does not use are greyed out."""

    def __init__(self, index: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        sec = CONTROLLER_SECTIONS[index]
        fields = [Field(f"{sec}.Degree", "Degree", "0..4")]
        fields += [Field(f"{sec}.s{j}", f"s{j}") for j in range(MAX_DEGREE + 1)]
        fields += [Field(f"{sec}.r{j}", f"r{j}") for j in range(1, MAX_DEGREE + 1)]
        super().__init__(f"Controller {ELEMENT_NAMES[index]} - General", params, defaults, fields,
                         opener=opener)
        self.section = sec

    def on_mount(self) -> None:
        super().on_mount()
        self._enable(self.params.get(f"{self.section}.Degree"))

    def on_field_changed(self, key: str) -> None:
        if key.endswith(".Degree"):
            try:
                degree = int(self._read(0))
            except ParameterError:
                return
            if 0 <= degree <= MAX_DEGREE:
                self._enable(degree)

    def _enable(self, degree: int) -> None:
        for i, f in enumerate(self.fields[1:], start=1):
            used = int(f.key.rsplit(".", 1)[1][1:]) <= degree  # s0..s4, r1..r4
            self.query_one(f"#row-{i}").set_class(not used, "-unused")
            self.query_one(f"#f-{i}", Input).disabled = not used
