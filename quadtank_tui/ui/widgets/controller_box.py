"""The Controller box (M5; thesis 5.3 "Controllers"): the 2x2 matrix, each
element with its main parameters, the type, Type and Reset.

Element ij maps error j to input i.  In a decentralized structure only 11 and 22
take part; 12 and 21 are shown as unused.  Values that differ from the defaults
are dim italic (the original's gray).
"""

from __future__ import annotations

from textual import events
from textual.app import ComposeResult
from textual.containers import Grid, Vertical
from textual.content import Content
from textual.reactive import reactive
from textual.widgets import Static

from quadtank_tui.core.parameters import CONTROLLER_SECTIONS, Parameters
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.values import fmt
from quadtank_tui.ui.windows.controller import ELEMENT_NAMES, TYPES, type_index, type_modified


def element_used(p: Parameters, index: int) -> bool:
    """Whether element 0..3 takes part in the current structure."""
    return p.control.structure.value == "FullMatrix" or index in (0, 3)


def _value(p: Parameters, defaults: Parameters, key: str, label: str) -> str:
    text = f"{label} {fmt(p.get(key))}"
    return f"[i dim]{text}[/]" if p.is_modified(key, defaults) else text


def element_lines(p: Parameters, defaults: Parameters, index: int) -> list[str]:
    """Markup lines describing one element (its main parameters)."""
    sec = CONTROLLER_SECTIONS[index]
    if p.control.family.value == "PID":
        i_on, d_on = p.get(f"{sec}.I"), p.get(f"{sec}.D")
        kind = "P" + ("I" if i_on else "") + ("D" if d_on else "")
        line2 = _value(p, defaults, f"{sec}.K", "K")
        if i_on:
            line2 += " " + _value(p, defaults, f"{sec}.Ti", "Ti")
        line3 = kind + (" " + _value(p, defaults, f"{sec}.Td", "Td") if d_on else "")
        return [line2, line3]
    degree = p.get(f"{sec}.Degree")
    num = " ".join(fmt(p.get(f"{sec}.s{j}")) for j in range(degree + 1))
    den = " ".join(["1"] + [fmt(p.get(f"{sec}.r{j}")) for j in range(1, degree + 1)])
    modified = any(p.is_modified(f"{sec}.{k}", defaults)
                   for k in ["Degree", *(f"s{j}" for j in range(5)), *(f"r{j}" for j in range(1, 5))])
    style = "i dim" if modified else "none"
    return [f"[{style}]n {degree}: {num}[/]", f"[{style}]d {den}[/]"]


class ElementCell(Static):
    """One element of the matrix; a click opens its window."""

    def __init__(self, index: int) -> None:
        super().__init__(id=f"element-{index}", classes="element")
        self.index = index

    def show(self, p: Parameters, defaults: Parameters) -> None:
        used = element_used(p, self.index)
        self.set_class(not used, "-unused")
        head = f"[b]{ELEMENT_NAMES[self.index]}[/] [dim]{self.index + 1}[/]"
        body = element_lines(p, defaults, self.index) if used else ["[dim]not used[/]"]
        self.update(Content.from_markup("\n".join([head, *body])))

    def on_click(self, event: events.Click) -> None:
        event.stop()
        self.post_message(ActionRequested(f"element({self.index})"))


class ControllerBox(Vertical):
    """Type line and the four cells; the screen sets `params` (attributes down)."""

    params: reactive[Parameters | None] = reactive(None)

    def __init__(self, defaults: Parameters, **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self.defaults = defaults
        self.border_title = "Controller"
        self.border_subtitle = "t type · 1-4 · C reset"

    def compose(self) -> ComposeResult:
        yield Static(id="controller-type")
        with Grid(id="matrix"):
            for n in range(4):
                yield ElementCell(n)

    def watch_params(self, p: Parameters | None) -> None:
        if p is None:
            return
        label = TYPES[type_index(p)][2]
        style = "i dim" if type_modified(p, self.defaults) else "b"
        self.query_one("#controller-type", Static).update(Content.from_markup(
            f"[{style} @click=screen.controller_type]{label}[/]  "
            "[@click=screen.reset_controllers]Reset[/]"))
        for cell in self.query(ElementCell):
            cell.show(p, self.defaults)
