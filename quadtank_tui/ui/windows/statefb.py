"""The State feedback window: the STATE FEEDBACK settings (Desautel, chapters 3-4).

Set sends them; the engine redesigns between two samples (bumpless) or refuses with
the key and the reason, which the window shows next to the field.  The gains, the
placed poles and delta are in the Controller box.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.widgets import Button

from quadtank_tui.core.parameters import STATEFB_SECTION, Parameters
from quadtank_tui.engine.commands import ResetControllers
from quadtank_tui.ui.windows.base import Field, ParamWindow

S = STATEFB_SECTION
FIELDS = (
    Field(f"{S}.Ts", "Ts", "s settling time"),
    Field(f"{S}.Poles", "Poles", "zeros | none | rad/s", text=True),
    Field(f"{S}.L3", "L3", "x L2^-1 anti-windup"),
    Field(f"{S}.Smart", "Smart int.", flag=True),
    Field(f"{S}.LevelMargin", "Margin", "cm below a top"),
    Field(f"{S}.Level1", "At h1", "cm (linearized)"),
    Field(f"{S}.Level2", "At h2", "cm (linearized)"),
)


class StateFeedbackWindow(ParamWindow):
    """Settling time, chosen poles, anti-windup and the operating point; Reset clears
    the integrators.  Opened like an element's window (1-4), so it takes an index."""

    def __init__(self, index: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        super().__init__("Controller - State feedback", params, defaults, FIELDS, opener=opener)

    def compose_buttons(self) -> ComposeResult:
        yield from super().compose_buttons()
        yield Button("Reset", id="reset_integrators")

    def action_reset_integrators(self) -> None:
        """Integrators to zero now (the window closes, nothing else changes)."""
        self.dismiss((ResetControllers(),))
