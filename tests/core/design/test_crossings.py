"""One crossover and margin search for the SISO design (core.design.frequency) and
the ICAD channels (core.icad): on a loop whose figures are known in closed form,
both give them (issue 18: the two copies were folded into one)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.frequency import crossings, margins, phase_crossings
from quadtank_tui.core.icad import _margins

# L(s) = 4 / (s + 1)^3: |L| = 1 at w = sqrt(4^(2/3) - 1), the phase -180 deg at
# w = sqrt(3), where |L| = 4/8: gain margin 2.
K = 4.0
WC = math.sqrt(K ** (2 / 3) - 1.0)
WP = math.sqrt(3.0)


def loop(w: np.ndarray | float) -> np.ndarray:
    return K / (1j * np.asarray(w) + 1.0) ** 3


def test_the_search_finds_the_closed_form_crossings() -> None:
    w = np.logspace(-2, 2, 400)
    assert crossings(lambda x: math.log(abs(loop(x))), w, np.log(np.abs(loop(w)))) == [pytest.approx(WC, rel=1e-10)]
    ph = -3.0 * np.arctan(w)
    assert phase_crossings(lambda x: -3.0 * math.atan(x), w, ph) == [pytest.approx(WP, rel=1e-10)]


def test_design_margins_and_an_icad_channel_agree_on_the_same_loop() -> None:
    w = np.logspace(-2, 2, 400)
    design = margins(DelayTF((K,), (1.0, 3.0, 3.0, 1.0)), w)
    channel = _margins(lambda x: complex(loop(x)), w, loop(w))
    assert design.crossover == pytest.approx(WC, rel=1e-9) and channel.crossover == pytest.approx(WC, rel=1e-9)
    assert design.gain_margin == pytest.approx(2.0, rel=1e-9) and channel.gain_margin == pytest.approx(2.0, rel=1e-9)
    pm = 180.0 - math.degrees(3.0 * math.atan(WC))
    assert design.phase_margin_deg == pytest.approx(pm, abs=1e-7)
    assert channel.phase_margin_deg == pytest.approx(pm, abs=1e-7)
