"""The Identify screen's method "physical": the constants of the plant in use (P-,
the engine's) fitted in a worker to a log of a rig whose pump 1 and outlet 1 differ,
the fit held against a second log, a progress bar, cancel, save as .par."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from textual.widgets import DataTable, SelectionList

from quadtank_tui.core.identify.physical import simulate
from quadtank_tui.core.plants.johansson import P_MINUS
from quadtank_tui.core.plants import QuadTank
from quadtank_tui.files.log_writer import format_header, format_row
from quadtank_tui.files.par import parse_par
from quadtank_tui.ui.screens.identify import IdentifyScreen

from bursts import burst  # noqa: E402

#: The rig: P- but pump 1 delivers 3.50 (not 3.33) cm^3/(V s) and outlet 1 is 0.075 cm^2.
RIG = QuadTank(P_MINUS.params).with_values(k1=3.50, a1=0.075)
H, ROWS = 5.0, 60


def rig_log(path: Path, seed: int) -> None:
    """ROWS rows at 5 s of the rig under a PRBS on both pumps, 10 mV sensor noise (fixed seed)."""
    rng = np.random.default_rng(seed)
    u = 3.0 + np.column_stack([np.repeat(rng.choice([-1.0, 1.0], ROWS // 6 + 1), 6)[:ROWS] for _ in range(2)])
    x = simulate(RIG, (12.4, 12.7, 1.8, 1.4), u, H)
    y = np.array([RIG.output(r) for r in x]) + 0.01 * rng.standard_normal((ROWS, 4))
    cols = np.column_stack([y[:, 0], y[:, 1], u[:, 0], u[:, 1], y[:, 2], y[:, 3]]) / 10.0
    path.write_text(format_header(["y1", "y2", "u1", "u2", "y3", "y4"], H, datetime(2000, 1, 1))
                    + "".join(format_row(r) for r in cols))


@pytest.fixture
def app(setup_app):
    Path("logs").mkdir(exist_ok=True)
    rig_log(Path("logs/rig-a.log"), 1)
    rig_log(Path("logs/rig-b.log"), 2)
    return setup_app


async def open_physical(pilot: Any) -> IdentifyScreen:
    """Identify (y), both logs ticked, the method cycled to physical in one burst,
    the constants: only k1 and a1 left ticked (Tab to the list, space on the others)."""
    await pilot.pause()
    await pilot.press("y")
    await pilot.pause()
    await burst(pilot, "space", "down", "space", "m", "m", "m", "m")
    screen = pilot.app.screen
    assert isinstance(screen, IdentifyScreen) and screen.method == "physical"
    free = screen.query_one("#free", SelectionList)
    free.focus()
    await pilot.pause()
    # ticked at first: a1 a2 a3 a4 k1 k2 gamma1 gamma2 (after A1..A4): untick a2..a4, k2, gamma1, gamma2
    await burst(pilot, *["down"] * 6, "space", "down", "space", "down", "space", "down", "down", "space",
                "down", "space", "down", "space")
    assert free.selected == ["a1", "k1"]
    return screen


async def fit(pilot: Any) -> None:
    await pilot.press("f")
    await pilot.app.workers.wait_for_complete()
    await pilot.pause()
    await pilot.pause()


def test_physical_fit_120x40(app, snap_compare) -> None:
    async def run_before(pilot: Any) -> None:
        await open_physical(pilot)
        await fit(pilot)

    assert snap_compare(app, terminal_size=(120, 40), run_before=run_before)


async def test_fit_validate_and_save_as_par(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await open_physical(pilot)
        await fit(pilot)
        view = screen.physical
        assert view is not None and view.fitted_logs == ("logs/rig-a.log",)
        got = {e.name: e for e in view.fit.constants}
        assert got["a1"].value == pytest.approx(0.075, rel=0.01) and got["k1"].value == pytest.approx(3.5, rel=0.01)
        assert abs(got["k1"].value - 3.5) < 4 * got["k1"].stderr
        assert [f.output for f in view.figures] == ["y1", "y2", "y3", "y4"]
        assert min(f.fit_percent for f in view.figures) > 90 and max(f.rms_v for f in view.figures) < 0.015
        table = screen.query_one("#compare", DataTable)
        assert table.row_count == 2 and [str(c) for c in table.get_row_at(0)][::3] == ["a1", "0.071"]
        assert "validation y1" in str(screen.query_one("#identify-status").render())
        await pilot.press("k")
        await pilot.pause()
        saved = parse_par(Path("logs/rig-a.par").read_text()).params.process_plant()
        assert saved.kind == "quadtank" and saved.values()["k1"] == pytest.approx(got["k1"].value, rel=1e-7)
        Path("logs/rig-a.par").write_text("kept")
        await pilot.press("k")                 # exists: asks, writes nothing
        await pilot.pause()
        assert Path("logs/rig-a.par").read_text() == "kept"
        assert "k again overwrites" in str(screen.query_one("#identify-status").render())
        await pilot.press("e", "k")            # another key withdrew the question: asks again
        await pilot.pause()
        assert Path("logs/rig-a.par").read_text() == "kept"
        await pilot.press("k")
        await pilot.pause()
        assert Path("logs/rig-a.par").read_text().startswith("% TANK PAR-file")


async def test_cancel_stops_a_running_fit(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await open_physical(pilot)
        await burst(pilot, "f", "c")
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        assert screen.physical is None and not screen._fitting
        assert "cancelled" in str(screen.query_one("#identify-status").render())
        assert not screen.query_one("#fit-progress").display
        await pilot.press("f")                 # and a new fit runs to the end
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        assert screen.physical is not None
