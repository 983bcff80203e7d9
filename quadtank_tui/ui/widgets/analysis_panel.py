"""What the current process setting implies (B1 on the Setup screen): the
linearized time constants, the transmission zeros and minimum / nonminimum phase.

The thesis's students had to work out by hand that gamma1 + gamma2 < 1 puts a zero
in the right half-plane; here the consequence of every valve, diameter or
operating-point change is shown next to it.  The numbers come from
``quadtank_tui.core.analysis.analyze`` at the setting's operating levels; this
widget only formats them (attributes down: the screen or a window sets `params`).
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

from rich.text import Text
from textual.reactive import reactive
from textual.widgets import Static

from quadtank_tui.core.parameters import Parameters, SimulationSettings
from quadtank_tui.core.plant import PlantError

if TYPE_CHECKING:
    from quadtank_tui.core.analysis import Analysis


@lru_cache(maxsize=32)
def analysis_of(sim: SimulationSettings) -> Analysis | str:
    """The analysis of a setting, or why there is none (cached: the screen redraws
    often, the setting changes rarely).  python-control is imported here, on the
    first analysis, not when the app starts: the Main screen never needs it."""
    from quadtank_tui.core.analysis import analyze

    try:
        return analyze(sim.plant(), sim.operating_levels())
    except PlantError as exc:
        return str(exc)


def zero_text(z: complex) -> str:
    """A zero as the user reads it: 4 decimals, sign always shown, RHP marked."""
    text = f"{z.real:+.4f}" if z.imag == 0 else f"{z.real:+.4f}{z.imag:+.4f}j"
    return text + (" (RHP)" if z.real > 0 else "")


def summary_lines(a: Analysis) -> list[Text]:
    """Four lines: time constants, zeros, phase with its reason, and the relative
    gain of the 1-1 pairing (negative at P+: pair u1 with y2)."""
    t = Text.assemble(("T1..T4 ", "bold"), "  ".join(f"{x:.1f}" for x in a.time_constants), " s")
    zeros = Text("Zeros   ", style="bold")
    for n, z in enumerate(a.zeros):
        zeros.append(("  " if n else "") + zero_text(z), style="bold red" if z.real > 0 else "")
    if not a.zeros:
        zeros.append("none")
    relation = ">" if a.gamma_sum > 1 else ("=" if a.gamma_sum == 1 else "<")
    phase = Text.assemble(
        ("γ1+γ2 ", "bold"), f"{a.gamma_sum:.2f} {relation} 1: ",
        (f"{a.phase} phase", "bold green" if a.phase == "minimum" else "bold red"),
    )
    rga = Text("RGA λ11 ", style="bold")
    rga.append("undefined (G(0) singular)" if a.rga is None else f"{a.rga[0, 0]:.2f}")
    return [t, zeros, phase, rga]


class AnalysisPanel(Static):
    """Time constants, zeros and phase of `params` (None: nothing shown yet)."""

    params: reactive[Parameters | None] = reactive(None)

    def watch_params(self, params: Parameters | None) -> None:
        if params is None:
            self.update("")
            return
        a = analysis_of(params.simulation)
        if isinstance(a, str):
            self.update(Text(f"No linearization: {a}", style="italic"))
            return
        self.update(Text("\n").join(summary_lines(a)))
        self.set_class(a.phase != "minimum", "-nonminimum")

    def refuse(self, reason: str) -> None:
        """No analysis while a value being edited is refused: an analysis of the
        last valid values would pass for one of the refused (valve 1.5 read as
        "minimum phase"); say why instead."""
        self.set_reactive(AnalysisPanel.params, None)
        self.update(Text(f"No analysis: {reason}", style="italic"))
        self.set_class(False, "-nonminimum")
