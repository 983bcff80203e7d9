"""The preview's two loops, predicted and simulated, each with its own element's
anti-windup time Tr (the prediction ran both loops with loop 1's)."""

from __future__ import annotations

import numpy as np

from quadtank_tui.core.design.pid_tuning import PIDTuning
from quadtank_tui.core.design.mimo import model_in_use
from quadtank_tui.core.design.preview import PreviewStep, preview
from quadtank_tui.core.parameters import PRESET


def test_loop_2s_tr_acts_in_the_prediction_as_in_the_simulation() -> None:
    """P-, loop 2 with a gain that drives its pump to the limit on the 0.1 step: a
    slow Tr of loop 2 (60 s against 1 s) winds its integrator up in the simulation
    and, now, in the prediction too; loop 1's Tr alone does not touch loop 2's step."""
    G = model_in_use(PRESET)
    plant = PRESET.process_plant()
    lv = PRESET.process_levels()
    op = plant.steady_inputs([lv[0], lv[1], None, None])
    pair = (PIDTuning(1.9, 62.7), PIDTuning(10.0, 20.0))

    def step2(tr: tuple[float, float]) -> PreviewStep:
        return preview(plant, op.x, op.u, pair, 1.0, window=150.0, model=G, tr=tr).steps[1]

    fast, slow, other = step2((1.0, 1.0)), step2((1.0, 60.0)), step2((60.0, 1.0))
    assert fast.sim.at_limit >= 1.0  # the pump does reach its limit: Tr matters
    sim_gap = np.max(np.abs(slow.simulated - fast.simulated))
    assert fast.predicted is not None and slow.predicted is not None and other.predicted is not None
    pred_gap = np.max(np.abs(slow.predicted - fast.predicted))
    assert sim_gap > 0.01 and abs(pred_gap - sim_gap) < 0.1 * sim_gap  # 0.0236 and 0.0236
    np.testing.assert_allclose(other.predicted, fast.predicted, atol=1e-9)
