"""Issue 43's figure items: `--align step` at the first reference step, the
identification figure's title without the logs' folders, and its levels in the
plant's unit (read back off the drawn lines)."""

from __future__ import annotations

import numpy as np
import pytest

from quadtank_tui.core.identify.experiment import Options, Record, identify
from quadtank_tui.core.identify.sampling import simulate
from quadtank_tui.core.parameters import PRESET
from quadtank_tui.files.figures.identification import identification_figure
from quadtank_tui.files.figures.runs import Run, align, scales


def test_align_step_is_at_the_first_reference_step() -> None:
    t = np.arange(0.0, 100.0, 1.0)
    r1 = np.where(t < 20, 0.5, np.where(t < 60, 0.6, 0.55))  # steps at 20 s and at 60 s
    aligned = align(Run("a", t, {"r1": r1, "y1": r1}), "step", "a.log")
    assert aligned.t[20] == 0.0 and aligned.t[0] == -20.0
    only_r2 = align(Run("b", t, {"r2": np.where(t < 35, 0.4, 0.5)}), "step", "b.log")
    assert only_r2.t[35] == 0.0


def test_the_identification_figure_names_its_logs_and_draws_cm() -> None:
    rows = 600
    rng = np.random.default_rng(4)
    du = np.r_[0.0, np.repeat(rng.choice([-0.02, 0.02], rows // 30 + 1), 30)[: rows - 1]]
    y = 0.5 + simulate(np.array([2.0]), np.array([30.0, 1.0]), 1.0, du)
    ident = identify([Record("/home/student/lab/logs/prbs.log", 1.0, {"u1": 0.3 + du, "y1": y})],
                     Options(method="oe", outputs=("y1",)))
    units = scales("cm", PRESET.process_plant())
    fig = identification_figure(ident, units=units)
    title = fig.get_suptitle()
    assert "prbs.log" in title and "/home" not in title
    ax = fig.axes[0]
    measured = next(ln for ln in ax.get_lines() if ln.get_gid() == "G11:measured")
    k = ident.elements[("y1", "u1")].split
    assert np.asarray(measured.get_ydata()) == pytest.approx(y[k:] * units["y1"].factor)
    assert units["y1"].factor > 10 and ax.get_ylabel() == f"y1 ({units['y1'].unit})"
    plain = identification_figure(ident)
    assert plain.axes[0].get_ylabel() == "y1 (normalized)"
