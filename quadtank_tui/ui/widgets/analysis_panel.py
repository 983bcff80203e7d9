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
from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.spec import PlantSpec

if TYPE_CHECKING:
    from quadtank_tui.core.analysis import Analysis


#: Set once python-control and scipy are imported (seconds, on a loaded machine):
#: from then on an analysis takes milliseconds and is done at once.
_READY = threading.Event()


def warm_up(sim: SimulationSettings | None = None) -> None:
    """Import the analysis stack (the Main screen does it in a worker thread after
    its first frame, so Setup opens at once) by analysing `sim` (default: the
    preset's setting), which also caches the analysis Setup shows first.  The
    analysis imports scipy.linalg only when it runs: importing the module alone
    left that second (on a loaded machine) to the Setup screen's first open."""
    if sim is None:
        from quadtank_tui.core.parameters import PRESET

        sim = PRESET.simulation
    analysis_of(sim)
    _READY.set()


def analysis_ready() -> bool:
    return _READY.is_set()


@lru_cache(maxsize=32)
def analysis_of(sim: SimulationSettings) -> Analysis | str:
    """The analysis of a setting, or why there is none (cached: the screen redraws
    often, the setting changes rarely).  The analysis (numpy, scipy.linalg) is
    imported here, on the first analysis, not when the app starts: the Main
    screen never needs it."""
    from quadtank_tui.core.analysis import analyze

    try:
        return analyze(sim.plant(), sim.operating_levels())
    except PlantError as exc:
        return str(exc)
    finally:
        _READY.set()  # the stack is imported now: later analyses are done at once


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


@lru_cache(maxsize=32)
def plant_lines(spec: PlantSpec, k1: tuple, k2: tuple) -> list[Text] | str:
    """Another plant (core.plants.report): time constants, zeros and, for a 2x2 loop,
    the ICAD channel margins of the diagonal controllers in use (volts per volt)."""
    from quadtank_tui.core.icad import analyze_icad
    from quadtank_tui.core.plants.report import report

    try:
        r = report(spec.plant(), spec.levels)
    except (PlantError, ValueError) as exc:
        return str(exc)
    lines = [Text.assemble(("T ", "bold"), "  ".join(f"{-1 / p.real:.1f}" for p in r.poles), " s")]
    if r.zeros is not None:
        zeros = Text("Zeros   ", style="bold")
        zeros.append("  ".join(zero_text(z) for z in r.zeros) or "none")
        lines.append(zeros)
    if r.rga is not None:
        lines.append(Text.assemble(("RGA λ11 ", "bold"), f"{r.rga[0, 0]:.2f}"))
    if r.model.C.shape[0] == 2 == r.model.B.shape[1] and k1[0] and k2[0]:
        icad = analyze_icad(r.model, k1, k2)
        for i, c in enumerate(icad.channels, start=1):
            wc = "none" if c.crossover is None else f"{c.crossover:.3g} rad/s"
            pm = "-" if c.phase_margin_deg is None else f"{c.phase_margin_deg:.0f}°"
            lines.append(Text.assemble((f"C{i} ", "bold"), f"ωc {wc}  PM {pm}"))
        lines.append(Text.assemble(("ICAD ", "bold"), f"γ(0) {icad.gamma_at_0:.2f}  ",
                                   ("stable" if icad.stable else "UNSTABLE", "bold green" if icad.stable else "bold red")))
    return lines


def diagonal_pi(params: Parameters) -> tuple[tuple, tuple]:
    """The diagonal PI elements as (num, den) in volts per volt, hashable; empty
    when the controllers are not PID or an element is off (no ICAD shown then)."""
    out = []
    plant = params.process_plant()
    for i, element in ((0, params.controllers[0]), (1, params.controllers[3])):
        pid = element.pid
        if params.control.family.value != "PID" or pid.K == 0 or i >= len(plant.inputs):
            return ((), ()), ((), ())
        scale = plant.inputs[i].full_scale / 10.0
        num = (pid.K * scale * pid.Ti, pid.K * scale) if pid.integral else (pid.K * scale,)
        den = (pid.Ti, 0.0) if pid.integral else (1.0,)
        out.append((num, den))
    return out[0], out[1]


class AnalysisPanel(Static):
    """Time constants, zeros and phase of `params` (None: nothing shown yet).

    Until the analysis stack is imported (see warm_up) the analysis runs in a
    worker thread and the panel says so: the screen opens at once either way."""

    params: reactive[Parameters | None] = reactive(None)

    def watch_params(self, params: Parameters | None) -> None:
        if params is None:
            self.update("")
            return
        if params.process is not None:
            lines = plant_lines(params.process, *diagonal_pi(params))
            self.update(Text(f"No linearization: {lines}", style="italic") if isinstance(lines, str)
                        else Text("\n").join(lines))
            self.set_class(False, "-nonminimum")
            return
        if analysis_ready():
            self._show(analysis_of(params.simulation))
            return
        self.update(Text("Analysing...", style="dim italic"))
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

    def refuse(self, reason: str) -> None:
        """No analysis while a value being edited is refused: an analysis of the
        last valid values would pass for one of the refused (valve 1.5 read as
        "minimum phase"); say why instead."""
        self.set_reactive(AnalysisPanel.params, None)
        self.update(Text(f"No analysis: {reason}", style="italic"))
        self.set_class(False, "-nonminimum")
