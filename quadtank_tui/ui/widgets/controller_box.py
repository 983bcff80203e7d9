"""The Controller box (M5; thesis 5.3 "Controllers"): the 2x2 matrix, each
element with its main parameters, the type, Type and Reset.

Element ij maps error j to input i.  In a decentralized structure only 11 and 22
take part; 12 and 21 are shown as unused.  Values that differ from the defaults
are dim italic (the original's gray).  The state feedback has no elements: the box
shows its gains L1, L2, the placed poles (z) and delta instead; the MPC its
horizons and weights, its solves, faults and solve times.
"""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from textual import events
from textual.app import ComposeResult
from textual.containers import Grid, Vertical
from textual.content import Content
from textual.reactive import reactive
from textual.widgets import Static

from quadtank_tui.core.controllers.mpc.info import MPCInfo
from quadtank_tui.core.parameters import CONTROLLER_SECTIONS, Parameters
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.values import fmt
from quadtank_tui.ui.labels import ELEMENT_NAMES, TYPES, type_index, type_modified

if TYPE_CHECKING:  # scipy behind it: the Main screen starts without the analysis stack
    from quadtank_tui.core.controllers.statefb.quadtank import StateFeedbackInfo


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


def _numbers(row: tuple[float, ...]) -> str:
    return " ".join(f"{x:.3g}" for x in row)


def _pole(z: complex) -> str:
    return f"{z.real:.4f}" if z.imag == 0 else f"{z.real:.4f}±{abs(z.imag):.4f}i"


def statefb_lines(info: StateFeedbackInfo, p: Parameters) -> list[str]:
    """Markup lines of the state feedback in use: delta, placed poles, gains."""
    s = p.statefb
    limit = f" [reverse]{info.limited} limit[/]" if info.limited else ""
    lines = [f"[b]δ[/] {info.delta:.3f} Ts {s.settling_time:g} s {'smart' if s.smart else 'plain'}{limit}"]
    lines.append("[b]z[/] " + " ".join(_pole(z) for z in info.poles_z if z.imag >= 0))
    for name, M in (("L1", info.L1), ("L2", info.L2)):
        lines += [f"[b]{name if i == 0 else '  '}[/] {_numbers(row)}" for i, row in enumerate(M)]
    return lines


class WholeCell(Static):
    """The cell of a type that owns the 2x2 as a whole: its lines, or "no design
    yet"; a click opens its window (element 1's key)."""

    def show_lines(self, lines: list[str] | None) -> None:
        self.update(Content.from_markup("\n".join(lines if lines is not None else ["[dim]no design yet[/]"])))

    def on_click(self, event: events.Click) -> None:
        event.stop()
        self.post_message(ActionRequested("element(0)"))


class StateFeedbackCell(WholeCell):
    """The state feedback's design in use."""

    def show(self, info: StateFeedbackInfo | None, p: Parameters) -> None:
        self.show_lines(statefb_lines(info, p) if info is not None else None)


def mpc_lines(info: MPCInfo, p: Parameters) -> list[str]:
    """Markup lines of the MPC in use: horizons and weights, solves and faults, the
    solve times (ms) and the solver's status when it is not "solved"."""
    s = p.mpc
    faults = f"[reverse]faults {info.faults}[/]" if info.faults else "faults 0"
    step = f"x{info.step_s:g}s" if info.step_s > 1.5 * p.tsamp else ""  # a prediction step of k samples
    lines = [f"[b]N[/] {info.horizon}{step} [b]Nu[/] {info.moves}",
             f"[b]Q[/] {s.output_weight:g} [b]R[/] {s.input_weight:g} [b]S[/] {s.rate_weight:g}",
             f"solves {info.solves} {faults}",
             f"p50 {info.p50_ms:.2f} p99 {info.p99_ms:.2f} ms",
             f"slow {info.slow} (> Ts/10)"]
    if info.status and info.status != "solved":
        lines.append(f"[dim]{Content(info.status).markup}[/]")
    return lines


class MPCCell(WholeCell):
    """The MPC in use."""

    def show(self, info: MPCInfo | None, p: Parameters) -> None:
        self.show_lines(mpc_lines(info, p) if info is not None else None)


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
    #: The state feedback in use (from the snapshot), None with the other types.
    statefb: reactive[StateFeedbackInfo | None] = reactive(None)
    #: The MPC in use (from the snapshot), None with the other types.
    mpc: reactive[MPCInfo | None] = reactive(None)

    def __init__(self, defaults: Parameters, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.defaults = defaults
        self.border_title = "Controller"
        self.border_subtitle = "t type · 1-4 · C reset"

    def compose(self) -> ComposeResult:
        yield Static(id="controller-type")
        with Grid(id="matrix"):
            for n in range(4):
                yield ElementCell(n)
        yield StateFeedbackCell(id="statefb", classes="element")
        yield MPCCell(id="mpc", classes="element")

    def watch_params(self, p: Parameters | None) -> None:
        if p is None:
            return
        label = TYPES[type_index(p)][2]
        style = "i dim" if type_modified(p, self.defaults) else "b"
        self.query_one("#controller-type", Static).update(Content.from_markup(
            f"[{style} @click=screen.controller_type]{label}[/]  "
            "[@click=screen.reset_controllers]Reset[/]"))
        sf = p.control.family.value == "State feedback"
        mpc = p.control.family.value == "MPC"
        self.query_one("#matrix").display = not (sf or mpc)
        cell_sf = self.query_one(StateFeedbackCell)
        cell_sf.display = sf
        cell_mpc = self.query_one(MPCCell)
        cell_mpc.display = mpc
        if sf:
            cell_sf.show(self.statefb, p)
            return
        if mpc:
            cell_mpc.show(self.mpc, p)
            return
        for cell in self.query(ElementCell):
            cell.show(p, self.defaults)

    def watch_statefb(self, info: StateFeedbackInfo | None) -> None:
        if self.params is not None and self.params.control.family.value == "State feedback":
            self.query_one(StateFeedbackCell).show(info, self.params)

    def watch_mpc(self, info: MPCInfo | None) -> None:
        if self.params is not None and self.params.control.family.value == "MPC":
            self.query_one(MPCCell).show(info, self.params)
