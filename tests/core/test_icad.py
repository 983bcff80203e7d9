"""ICAD on Murray-Smith's coupled tanks (004_..., sections 3-4; issue 14)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from quadtank_tui.core.icad import analyze_icad, channel_responses, pi_controller
from quadtank_tui.core.plants import CoupledTITO, QuadTank
from quadtank_tui.core.plants.linear import LinearModel
from quadtank_tui.core.plants import johansson as qt

# his optimised controllers (27), (28), volts per volt
K1 = ((5.0 * 6.2, 5.0), (1.0, 0.0))
K2 = ((0.56 * 10.0, 0.56), (1.0, 0.0))
H0 = (0.115, 0.071)


def plant_v() -> LinearModel:
    """From pump volts to sensor volts at his design point."""
    return CoupledTITO().control_model(H0)


def test_published_crossovers_and_phase_margins() -> None:
    """Figures 6 and 7: about 0.8 and 0.2 rad/s, phase margins above 70 deg
    (control.md: 0.78 and 0.156 rad/s, 80 and 76 deg on G_V)."""
    r = analyze_icad(plant_v(), K1, K2)
    c1, c2 = r.channels
    assert c1.crossover == pytest.approx(0.7817, abs=5e-4)
    assert c2.crossover == pytest.approx(0.1565, abs=5e-4)
    assert c1.phase_margin_deg == pytest.approx(80.3, abs=0.1)
    assert c2.phase_margin_deg == pytest.approx(75.8, abs=0.1)
    assert c1.phase_margin_deg is not None and c2.phase_margin_deg is not None
    assert c1.phase_margin_deg > 70 and c2.phase_margin_deg > 70
    assert len(c1.crossovers) == len(c2.crossovers) == 1
    assert r.stable
    assert r.min_distance_to_1 > 0.4  # gamma h_j stays far from (1, 0): the margins are robust


def test_structure_function_at_steady_state_is_the_physics() -> None:
    """gamma(0) = g12 g21 / (g11 g22) = alpha1 / (alpha1 + alpha2) = 0.519 on his
    equation (11).  The published 0.48 = alpha2 / (alpha1 + alpha2) (23) follows from
    (15), which prints g21(0) = 1/alpha1 where (11) gives 1/alpha2 (a tank-1 inflow
    leaves through the drain: dH2 = dQ1 / alpha2).  Reported, not forced."""
    p = CoupledTITO()
    G = plant_v()
    al1 = -G.A[0, 0] * p.A1
    al2 = -G.A[1, 1] * p.A2 - al1
    r = analyze_icad(G, K1, K2)
    assert r.gamma_at_0 == pytest.approx(al1 / (al1 + al2), rel=1e-9)
    assert r.gamma_at_0 == pytest.approx(0.5186, abs=1e-4)
    # the printed formula: g21(0) = 1/alpha1 instead of 1/alpha2
    g = G.dcgain() / (p.Gd * p.Gp)
    assert g[1, 0] == pytest.approx(1 / al2, rel=1e-9)
    printed = g[0, 1] * (1 / al1) / (g[0, 0] * g[1, 1])
    assert printed == pytest.approx(al2 / (al1 + al2), rel=1e-9)
    assert round(printed, 2) == 0.48


def test_structure_function_closed_form() -> None:
    """(23) with the physical gain: gamma(s) = (alpha1/(alpha1+alpha2)) /
    ((1 + s A1/alpha1)(1 + s A2/(alpha1+alpha2)))."""
    p = CoupledTITO()
    G = plant_v()
    al1 = -G.A[0, 0] * p.A1
    al2 = -G.A[1, 1] * p.A2 - al1
    w = np.logspace(-4, 1, 50)
    s = 1j * w
    expected = (al1 / (al1 + al2)) / ((1 + s * p.A1 / al1) * (1 + s * p.A2 / (al1 + al2)))
    got = channel_responses(G, K1, K2, w)["gamma"]
    np.testing.assert_allclose(got, expected, rtol=1e-9)


def test_si_plant_crosses_over_near_3000_rad_s() -> None:
    """control.md: on the SI plant (m per m^3/s) the volt-per-volt controllers
    cross over some 4000 times higher."""
    p = CoupledTITO()
    G = plant_v()
    si = dataclasses.replace(G, B=G.B / p.Gp, C=G.C / p.Gd)
    r = analyze_icad(si, K1, K2, w=np.logspace(-3, 6, 3000))
    crossover = r.channels[0].crossover
    assert crossover is not None and 2000 < crossover < 5000


def test_channels_satisfy_their_definition() -> None:
    w = np.logspace(-3, 1, 20)
    r = channel_responses(plant_v(), K1, K2, w)
    g = plant_v().freqresp(w)
    k1 = (31.0 * 1j * w + 5.0) / (1j * w)
    np.testing.assert_allclose(r["C1"], k1 * g[:, 0, 0] * (1 - r["gamma"] * r["h2"]), rtol=1e-12)
    np.testing.assert_allclose(r["h1"], k1 * g[:, 0, 0] / (1 + k1 * g[:, 0, 0]), rtol=1e-12)


def test_unstable_loop_is_reported() -> None:
    """P+ with both PI gains positive cannot be stabilized (control.md: det G+(0) < 0)."""
    G = QuadTank(qt.P_PLUS.params).control_model(qt.P_PLUS.op.x)
    r = analyze_icad(G, pi_controller(1.5, 110.0), pi_controller(0.12, 220.0))
    assert not r.stable
    assert r.gamma_at_0 > 1.0  # the structure function beyond (1, 0) at steady state
    ok = analyze_icad(G, pi_controller(1.5, 110.0), pi_controller(-0.12, 220.0))
    assert ok.stable


def test_pi_controller_form() -> None:
    """K (1 + 1/(Ti s)) with K = 31, Ti = 6.2 is his 5 (1 + 6.2 s) / s."""
    num, den = pi_controller(31.0, 6.2)
    s = 0.3j
    assert np.polyval(num, s) / np.polyval(den, s) == pytest.approx(5 * (1 + 6.2 * s) / s, rel=1e-12)


def test_json_keys() -> None:
    d = analyze_icad(plant_v(), K1, K2).to_dict()
    assert {"crossover", "phase_margin_deg", "gain_margin", "gamma_at_0", "min_distance_to_1"} <= set(d)
    assert d["gain_margin"] == [None, None]  # the phase never reaches -180 deg
