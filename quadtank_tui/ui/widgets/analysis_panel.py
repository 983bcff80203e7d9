"""What the current process setting implies (B1 on the Setup screen): the
linearized time constants, the transmission zeros and minimum / nonminimum phase.

The thesis's students had to work out by hand that gamma1 + gamma2 < 1 puts a zero
in the right half-plane; here the consequence of every valve, diameter or
operating-point change is shown next to it.  The numbers come from
``quadtank_tui.core.analysis.analyze`` at the setting's operating levels; this
widget only formats them (attributes down: the screen or a window sets `params`).
"""

from __future__ import annotations

import threading
from functools import lru_cache
from typing import TYPE_CHECKING

from rich.text import Text
from textual import work
from textual.reactive import reactive
from textual.widgets import Static

from quadtank_tui.core.parameters import Parameters, SimulationSettings
from quadtank_tui.core.plant import PlantError

if TYPE_CHECKING:
    from quadtank_tui.core.analysis import Analysis


#: Set once python-control and scipy are imported (seconds, on a loaded machine):
#: from then on an analysis takes milliseconds and is done at once.
_READY = threading.Event()


def warm_up() -> None:
    """Import the analysis stack (the Main screen does it in a worker thread after
    its first frame, so Setup opens at once)."""
    import quadtank_tui.core.analysis  # noqa: F401

    _READY.set()


def analysis_ready() -> bool:
    return _READY.is_set()


@lru_cache(maxsize=32)
def analysis_of(sim: SimulationSettings) -> Analysis | str:
    """The analysis of a setting, or why there is none (cached: the screen redraws
    often, the setting changes rarely).  python-control is imported here, on the
    first analysis, not when the app starts: the Main screen never needs it."""
    from quadtank_tui.core.analysis import analyze

    _READY.set()
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
    """Time constants, zeros and phase of `params` (None: nothing shown yet).

    Until the analysis stack is imported (see warm_up) the analysis runs in a
    worker thread and the panel says so: the screen opens at once either way."""

    params: reactive[Parameters | None] = reactive(None)

    def watch_params(self, params: Parameters | None) -> None:
        if params is None:
            self.update("")
            return
        if analysis_ready():
            self._show(analysis_of(params.simulation))
            return
        self.update(Text("Analysing (loading python-control)...", style="dim italic"))
        self._analyse(params)

    @work(thread=True, exclusive=True, group="analysis", exit_on_error=False)
    def _analyse(self, params: Parameters) -> None:
        try:
            result: Analysis | str = analysis_of(params.simulation)
        except Exception as exc:  # noqa: BLE001 - say it in the panel, not a traceback
            result = f"the analysis failed: {type(exc).__name__}: {exc}"
        self.app.call_from_thread(self._show_if_current, params, result)

    def _show_if_current(self, params: Parameters, a: Analysis | str) -> None:
        if params == self.params:
            self._show(a)

    def _show(self, a: Analysis | str) -> None:
        if isinstance(a, str):
            self.update(Text(f"No linearization: {a}", style="italic"))
            return
        self.update(Text("\n").join(summary_lines(a)))
        self.set_class(a.phase != "minimum", "-nonminimum")
