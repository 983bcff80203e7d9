"""The MPC window: the MPC section's settings (issue 26) - horizons and the
prediction step, weights, limits and preview.

Set sends them as one SetParams; the window checks them together first (a control
horizon longer than the horizon, a weight out of range: the field and the reason,
nothing sent), and the engine designs the new MPC between two samples or refuses
with the key and the reason, the parameters in force unchanged.  The solves, faults
and solve times are in the Controller box.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.widgets import Button, Label

from quadtank_tui.core.parameters import MPC_SECTION, Parameters
from quadtank_tui.engine.commands import ResetControllers
from quadtank_tui.ui.windows.base import Field, ParamWindow

S = MPC_SECTION
FIELDS = (
    Field(f"{S}.Horizon", "Horizon", "prediction steps (N)"),
    Field(f"{S}.Step", "Step", "s per prediction step (0: Ts)"),
    Field(f"{S}.ControlHorizon", "Ctrl hor.", "steps (0: N)"),
    Field(f"{S}.OutputWeight", "Output wt.", "Q, per range^2"),
    Field(f"{S}.InputWeight", "Input wt.", "R, per range^2"),
    Field(f"{S}.RateWeight", "Rate wt.", "S, on u(k)-u(k-1)"),
    Field(f"{S}.RateLimit", "Rate limit", "V/s (0: none)"),
    Field(f"{S}.LevelMargin", "Margin", "cm below a top"),
    Field(f"{S}.Preview", "Preview", flag=True),
)


class MPCWindow(ParamWindow):
    """Horizons, weights, limits and preview; Reset starts the disturbance estimate
    and the counts again.  Opened like an element's window (1-4), so it takes an index."""

    def __init__(self, index: int, params: Parameters, defaults: Parameters, *,
                 opener: str | None = None) -> None:
        super().__init__("Controller - MPC", params, defaults, FIELDS, opener=opener)

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        yield Label("Pumps 0-10 V are hard limits, levels 0 to the top less the margin soft "
                    "ones; the plant is linearized at its operating levels (Setup).", classes="hint")

    def compose_buttons(self) -> ComposeResult:
        yield from super().compose_buttons()
        yield Button("Reset", id="reset_integrators")

    def action_reset_integrators(self) -> None:
        """The disturbance estimate and the counts start again (the window closes)."""
        self.dismiss((ResetControllers(),))
