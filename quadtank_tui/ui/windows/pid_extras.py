"""The Setup screen's PID window (thesis 5.4, Figure 38; S3): Main's PID window -
K, Ti, Td, the I/D enables, Reset - plus the extras the original kept for Setup:
N (maximum derivative gain), Tr (anti-windup tracking time), a and b (setpoint
weights of the D and P parts, in [0, 1]).

    U = K [ b R - Y + 1/(s Ti) (R - Y) + s Td / (1 + s Td / N) (a R - Y) ]
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.widgets import Label

from quadtank_tui.core.parameters import CONTROLLER_SECTIONS, Parameters
from quadtank_tui.ui.windows.base import Field
from quadtank_tui.ui.windows.controller_windows import PIDWindow


def extra_fields(section: str) -> tuple[Field, ...]:
    """The PID parameters only Setup shows, in Figure 38's order."""
    return (
        Field(f"{section}.N", "N", "max D gain"),
        Field(f"{section}.Tr", "Tr", "s, tracking"),
        Field(f"{section}.a", "a", "D weight 0..1"),
        Field(f"{section}.b", "b", "P weight 0..1"),
    )


class PIDExtrasWindow(PIDWindow):
    """Every PID parameter of element 11, 12, 21 or 22."""

    def __init__(self, index: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        super().__init__(index, params, defaults, opener=opener)
        self.fields = self.fields + extra_fields(CONTROLLER_SECTIONS[index])

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        yield Label("A change while running is bumpless.", classes="hint")
