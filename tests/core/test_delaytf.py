"""DelayTF: the model type that identification produces and design consumes."""

from __future__ import annotations

import cmath

import numpy as np
import pytest

from quadtank_tui.core.delaytf import DelayTF, ModelError


def test_first_order_with_delay_frequency_response_is_exact() -> None:
    g = DelayTF((2.0,), (5.0, 1.0), 3.0)
    w = 0.4
    expected = 2.0 / (5.0 * 1j * w + 1.0) * cmath.exp(-1j * w * 3.0)
    assert g.freqresp(w) == pytest.approx(expected, rel=1e-14)
    assert g.static_gain == 2.0 and g.integrators == 0


def test_integrating_model_reports_its_velocity_gain() -> None:
    g = DelayTF((-0.00652,), (49.33, 1.0, 0.0), 2.0)
    assert g.integrators == 1
    assert g.static_gain == pytest.approx(-0.00652)
    assert g.poles() == pytest.approx(np.array([-1 / 49.33, 0.0]), abs=1e-12)


def test_leading_zeros_are_trimmed_and_improper_models_refused() -> None:
    assert DelayTF((0.0, 1.0), (0.0, 2.0, 1.0)).den == (2.0, 1.0)
    with pytest.raises(ModelError, match="improper"):
        DelayTF((1.0, 0.0, 0.0), (1.0, 1.0))
    with pytest.raises(ModelError, match="delay"):
        DelayTF((1.0,), (1.0, 1.0), -1.0)
    with pytest.raises(ModelError, match="finite"):
        DelayTF((float("nan"),), (1.0, 1.0))
