"""The MPC window: the MPC section's settings - horizons and the
prediction step, weights, limits, preview, the disturbance model, the measured
levels and the price of a level-limit violation.

Set sends them as one SetParams; the window checks them together first (a control
horizon longer than the horizon, a weight out of range, a model that is neither
input nor output, a tank the plant does not have or a tracked one left unmeasured:
the field and the reason, nothing sent), and the engine designs the new MPC
between two samples or refuses with the key and the reason, the parameters in
force unchanged.  The solves, faults
and solve times are in the Controller box.
"""

from __future__ import annotations

from typing import Any

from textual.app import ComposeResult
from textual.widgets import Label

from quadtank_tui.core.parameters import MPC_SECTION
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.ui.windows.base import Field, WholeControllerWindow

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
    Field(f"{S}.Disturbance", "Disturbance", "input or output (offset-free)", text=True),
    Field(f"{S}.Measured", "Measured", "all, or tanks: 1 2", text=True),
    Field(f"{S}.SlackWeight", "Slack wt.", "per level-limit violation"),
)


class MPCWindow(WholeControllerWindow):
    """Horizons, weights, limits and preview; Reset starts the disturbance estimate
    and the counts again."""

    controller_title = "Controller - MPC"
    controller_fields = FIELDS

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        yield Label("Pumps 0-10 V hard limits, levels 0..top-margin soft; linearized at the "
                    "operating levels (Setup).", classes="hint")

    def values(self) -> dict[str, Any] | None:
        """The fields' values, checked together and against the plant in use: the
        tanks named in Measured must exist, the tracked ones be among them, and input
        disturbances need as many measured levels as pumps."""
        out = super().values()
        if out is None:
            return None
        p = self.params.with_values(out)
        plant = p.process_plant()
        try:
            p.mpc.check_plant(plant.kind, len(plant.states), tuple(plant.controlled), len(plant.inputs))
        except ParameterError as exc:
            self._error(exc.field, exc.reason)
            return None
        return {k: p.get(k) for k in out}  # as the file writes them ("Output" is output)
