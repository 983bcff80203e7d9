"""The Identify screen: from Main by `y`, a fit in a worker on fixed logs, the
comparison with the physical model, keeping the model, bad logs refused."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from quadtank_tui.core.analysis import analyze
from quadtank_tui.core.identify.sampling import simulate
from quadtank_tui.core.plants.johansson import P_MINUS, steady_state_levels
from quadtank_tui.files.log_writer import format_header, format_row
from quadtank_tui.files.model import read_model
from quadtank_tui.ui.screens.identify import IdentifyScreen
from test_plot_kit import check_identify_plots

from bursts import burst  # noqa: E402

ROWS = 1200


def write_log(path: Path, columns: dict[str, np.ndarray]) -> None:
    names = list(columns)
    rows = np.column_stack([columns[n] for n in names])
    path.write_text(format_header(names, 1.0, datetime(2000, 1, 1)) + "".join(format_row(r) for r in rows))


def simo_logs(folder: Path) -> None:
    """The linearized P- process under a PRBS on u1, then on u2 (fixed seeds)."""
    h = steady_state_levels(P_MINUS.op.u, P_MINUS.params)
    a = analyze(P_MINUS.params, h)
    folder.mkdir(exist_ok=True)
    for i in range(2):
        rng = np.random.default_rng(i + 1)
        du = np.r_[0.0, np.repeat(rng.choice([-0.015, 0.015], ROWS // 60 + 1), 60)[: ROWS - 1]]
        cols: dict[str, np.ndarray] = {}
        for o in range(2):
            e = a.G[o][i]
            den = np.array([1.0])
            for T in e.lags:
                den = np.polymul(den, [T, 1.0])
            cols[f"y{o + 1}"] = P_MINUS.params.kc * h[o] / 10 + simulate(np.array([e.gain]), den, 1.0, du)
        cols["u1"] = 0.30 + (du if i == 0 else 0.0 * du)
        cols["u2"] = 0.30 + (du if i == 1 else 0.0 * du)
        write_log(folder / f"pminus-u{i + 1}.log", cols)


async def fit_both(pilot: Any) -> None:
    await pilot.pause()
    await pilot.press("y")
    await pilot.pause()
    await pilot.press("space", "down", "space", "f")
    await pilot.app.workers.wait_for_complete()
    await pilot.pause()
    await pilot.pause()


@pytest.fixture
def app(setup_app):
    simo_logs(Path("logs"))
    return setup_app


def test_identify_after_a_fit_120x40(app, snap_compare) -> None:
    # The coherence (v) depends on the data alone; the residuals of a noiseless fit
    # are rounding noise whose correlation moves with the BLAS's summation order.
    assert snap_compare(app, terminal_size=(120, 40), run_before=fit_both, press=["v"])


def test_identify_before_a_fit_80x24(app, snap_compare) -> None:
    # The highlighted log's signals, before any fit.
    assert snap_compare(app, terminal_size=(80, 24), press=["y"])


async def test_fit_compares_keeps_and_returns(app) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await fit_both(pilot)
        screen = pilot.app.screen
        assert isinstance(screen, IdentifyScreen)
        view = screen.view
        assert view is not None and view.comparison is not None
        ident = view.ident
        assert set(ident.elements) == {("y1", "u1"), ("y2", "u1"), ("y1", "u2"), ("y2", "u2")}
        a = view.comparison.physical
        assert np.abs(ident.system.static_gains / a.static_gains - 1).max() < 0.01
        assert np.array(ident.system.zeros).real == pytest.approx([z.real for z in a.zeros], rel=0.02)
        # The spectral estimate (checked against a known answer in core's tests) next to
        # the model's gain, up to 0.1 Hz; the model's is G11's: 2.596/(1 + 62.4 s).
        w, est, mod = view.frequency[("y1", "u1")]
        assert w.size == est.size == mod.size == 72 and w.max() == pytest.approx(2 * np.pi * 0.1)
        assert mod[0] == pytest.approx(2.596 / abs(1 + 62.36j * w[0]), rel=0.01)
        check_identify_plots(screen)
        status = screen.query_one("#identify-status")  # one line at 120 columns (issue 43)
        shown = [s.text.strip() for s in status.render_lines(status.content_region.reset_offset)]
        assert shown[0].startswith("n4sid:") or ": fit on the validation half" in shown[0], shown
        assert not any(shown[1:]), shown
        await pilot.press("v", "v")
        await pilot.pause()
        assert "spectral estimate" in str(screen.query_one("#lower").border_title)
        lags, r, band = view.residuals[("y1", "u1")]
        assert r[0] == pytest.approx(1.0) and band == pytest.approx(2.576 / np.sqrt(ROWS / 2), rel=1e-3)
        await pilot.press("k")
        await pilot.pause()
        model = read_model("logs/pminus-u1.model.json")
        assert model.method == "oe" and model.inputs == ("u1", "u2")
        await pilot.press("escape")
        await pilot.pause()
        assert not isinstance(pilot.app.screen, IdentifyScreen)
        assert pilot.app.engine.snapshot() is not None  # the process is untouched


async def test_a_bad_log_is_one_line_on_the_screen(app) -> None:
    for p in Path("logs").glob("*.log"):
        p.unlink()
    write_log(Path("logs/flat.log"), {"y1": np.full(200, 0.6), "u1": np.full(200, 0.3)})
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause()
        await pilot.press("y")
        await pilot.pause()
        await pilot.press("space", "f")
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        status = str(pilot.app.screen.query_one("#identify-status").render())
        assert "no input moves (u1 and u2 are constant)" in status
        assert pilot.app.screen.view is None


async def test_d_designs_on_the_identified_model(app) -> None:
    """d after a fit: the Design screen's loops start from the fitted G11 and G22,
    and its 2x2 design uses all four elements (lambda = T/5 at P-: Kc 1.916 and
    1.762 on the physical linearization; the identified model gives the same within 1 %)."""
    from textual.widgets import DataTable, Input

    from quadtank_tui.ui.model_text import model_text
    from quadtank_tui.ui.screens.design import DesignScreen

    async with app.run_test(size=(120, 40)) as pilot:
        await fit_both(pilot)
        ident = pilot.app.screen.view.ident
        g11, g22 = ident.system.elements[0][0], ident.system.elements[1][1]
        await pilot.press("d")
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        screen = pilot.app.screen
        assert isinstance(screen, DesignScreen)
        assert screen.loops[1].model is g11 and screen.loops[2].model is g22
        assert g11 is not None and screen.query_one("#model-1", Input).value == model_text(g11)
        assert screen.source == "the identified model (oe, pminus-u1.log, pminus-u2.log)"
        assert f"loop 1: 9 candidates on {model_text(g11)}" in str(screen.query_one("#design-status").render())
        assert screen.query_one("#design-table", DataTable).row_count == 9
        await pilot.press("2")
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()
        c1, c2 = screen.loops[1].chosen, screen.loops[2].chosen
        assert c1 is not None and c2 is not None
        assert c1.Kc == pytest.approx(1.916, rel=0.01) and c2.Kc == pytest.approx(1.762, rel=0.01)
        assert "closed loop stable" in str(screen.query_one("#design-mimo").render())
        # Esc goes back to Identify, and the footer says so (it said Main); the keys
        # typed right behind it are Identify's: m cycles its method (oe -> arx)
        assert screen.active_bindings["escape"].binding.description == "Identify"
        assert any("esc Identify" in s.text for s in screen._compositor.render_strips())
        ident_screen = pilot.app.screen_stack[-2]
        assert isinstance(ident_screen, IdentifyScreen) and ident_screen.method == "oe"
        await burst(pilot, "escape", "m")
        assert pilot.app.screen is ident_screen and ident_screen.method != "oe"


@pytest.mark.parametrize("fitted", [False, True])
async def test_a_resize_draws_the_plots_for_their_new_width(app, monkeypatch: pytest.MonkeyPatch, fitted: bool) -> None:
    """A plot's ticks are laid out for its width when it is drawn (plot_kit.axes):
    after the terminal changes size, the log's preview (or the fit) is drawn again
    for the width the plot now has, not with the ticks for the old one."""
    from quadtank_tui.ui.widgets import plot_kit
    from quadtank_tui.ui.widgets.plot_view import PlotView

    widths: list[int] = []
    axes = plot_kit.axes

    def recorded(fig: Any, xlim: Any, ylim: Any, width: int, height: int, **kw: Any) -> None:
        widths.append(width)
        axes(fig, xlim, ylim, width, height, **kw)
    monkeypatch.setattr(plot_kit, "axes", recorded)
    async with app.run_test(size=(120, 40)) as pilot:
        if fitted:
            await fit_both(pilot)
        else:
            await pilot.pause()
            await pilot.press("y")
            await pilot.pause()
        top = pilot.app.screen.query_one("#outputs", PlotView)
        assert widths and widths[-1] == top.content_size.width
        wide = top.content_size.width
        for size in ((80, 24), (120, 40)):
            await pilot.resize_terminal(*size)
            for _ in range(4):
                await pilot.pause()
            assert top.content_size.width != wide if size == (80, 24) else top.content_size.width == wide
            assert widths[-1] == top.content_size.width, (size, widths[-4:])
