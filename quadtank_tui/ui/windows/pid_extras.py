"""The Setup screen's PID window (thesis 5.4, Figure 38; S3): the Main screen's
K, Ti, Td and I/D enables, plus the extras the original kept for Setup -
N (maximum derivative gain), Tr (anti-windup tracking time), a and b (setpoint
weights of the D and P parts, in [0, 1]).

    U = K [ b R - Y + 1/(s Ti) (R - Y) + s Td / (1 + s Td / N) (a R - Y) ]
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.widgets import Label

from quadtank_tui.core.parameters import CONTROLLER_SECTIONS, Parameters
from quadtank_tui.ui.windows.base import Field, ParamWindow

#: Element 0..3 -> its place in the matrix (input i, error j).
ELEMENTS = ("11", "12", "21", "22")


def pid_fields(section: str) -> tuple[Field, ...]:
    """Every PID parameter of one element, in the order Figure 38 lists them."""
    return (
        Field(f"{section}.K", "K", "gain"),
        Field(f"{section}.Ti", "Ti", "s"),
        Field(f"{section}.Td", "Td", "s"),
        Field(f"{section}.I", "Integral", flag=True),
        Field(f"{section}.D", "Derivative", flag=True),
        Field(f"{section}.N", "N", "max D gain"),
        Field(f"{section}.Tr", "Tr", "s, tracking"),
        Field(f"{section}.a", "a", "D weight 0..1"),
        Field(f"{section}.b", "b", "P weight 0..1"),
    )


class PIDExtrasWindow(ParamWindow):
    """All PID parameters of element 11, 12, 21 or 22."""

    def __init__(self, index: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        super().__init__(f"Controller {ELEMENTS[index]} - PID", params, defaults,
                         pid_fields(CONTROLLER_SECTIONS[index]), opener=opener)
        self.index = index

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        yield Label("A change while running is bumpless.", classes="hint")
