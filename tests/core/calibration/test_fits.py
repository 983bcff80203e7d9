"""Sensor calibration by least squares against Desautel's published fit (section 2.3)."""

from __future__ import annotations

import pytest

from quadtank_tui.core.calibration.fits import CalibrationError, SensorCalibration, fit_sensor


@pytest.mark.parametrize(
    ("volts", "levels", "gain", "offset"),
    [
        # Desautel, Table 1 and equations 2.3.2 / 2.3.3: g1 = 5.4310, b1 = 0.2391;
        # g2 = 5.5558, b2 = 1.5420 (printed to 4 decimals).
        ((0.5864, 1.3422, 2.2396, 3.2051), (3.5, 7.5, 12.25, 17.75), 5.4310, 0.2391),
        ((0.2892, 1.0359, 1.9148, 2.8947), (3.25, 7.25, 12.0, 17.75), 5.5558, 1.5420),
    ],
)
def test_desautel_table_1(volts: tuple[float, ...], levels: tuple[float, ...], gain: float, offset: float) -> None:
    c = fit_sensor(volts, levels)
    assert c.gain == pytest.approx(gain, abs=2e-4)
    assert c.offset == pytest.approx(offset, abs=2e-4)
    assert 0 < c.rms < 0.2  # cm: the pairs are nearly, not exactly, on a line


def test_exact_pairs_are_recovered_and_inverted() -> None:
    c = fit_sensor([1.0, 2.0, 3.0], [2.3, 4.3, 6.3])
    assert (c.gain, c.offset) == pytest.approx((2.0, 0.3))
    assert c.rms == pytest.approx(0.0, abs=1e-12)
    assert c.volts(c.level(4.2)) == pytest.approx(4.2)


@pytest.mark.parametrize(
    ("volts", "levels", "match"),
    [([1.0], [2.0], "at least two"), ([1.0, 1.0], [2.0, 3.0], "same voltage"),
     ([1.0, 2.0], [2.0], "2 voltages but 1 levels"), ([1.0, float("nan")], [1.0, 2.0], "finite")],
)
def test_pairs_that_cannot_give_a_line(volts: list[float], levels: list[float], match: str) -> None:
    with pytest.raises(CalibrationError, match=match):
        fit_sensor(volts, levels)


def test_a_zero_gain_is_refused() -> None:
    with pytest.raises(CalibrationError, match="gain"):
        SensorCalibration(gain=0.0)


# --- outlet coefficients from the same settled levels (Desautel 2.3.1) ----------------------

def test_desautel_table_1_alphas() -> None:
    from quadtank_tui.core.calibration.fits import fit_cascade_outlets

    fit = fit_cascade_outlets((4, 5, 6, 7), (3.5, 7.5, 12.25, 17.75), (3.25, 7.25, 12.0, 17.75), beta=0.24813)
    alpha1, alpha2 = fit.coefficients
    assert alpha1 == pytest.approx(0.0097909, abs=5e-8)  # his 0.0097909
    assert alpha2 == pytest.approx(0.0098811, abs=5e-8)  # his 0.0098811


def test_quadtank_outlets_are_recovered_from_simulated_steady_states() -> None:
    from quadtank_tui.core.calibration.fits import fit_quadtank_outlets
    from quadtank_tui.core.plants.johansson import P_MINUS, steady_state_levels

    p = P_MINUS.params
    volts = [(2.5, 2.5), (3.0, 3.2), (3.4, 2.8)]
    levels = [steady_state_levels(v, p) for v in volts]
    fit = fit_quadtank_outlets(volts, levels, (p.k1, p.k2), (p.gamma1, p.gamma2), g=p.g)
    assert fit.coefficients == pytest.approx((p.a1, p.a2, p.a3, p.a4), rel=1e-9)
    assert fit.rms == pytest.approx(0.0, abs=1e-9)


def test_outlets_need_levels_above_zero() -> None:
    from quadtank_tui.core.calibration.fits import fit_cascade_outlets

    with pytest.raises(CalibrationError, match="cannot determine"):
        fit_cascade_outlets((4, 5), (0.0, 0.0), (0.0, 0.0), beta=0.25)
    with pytest.raises(CalibrationError, match="2 pump voltages but 1 levels"):
        fit_cascade_outlets((4, 5), (1.0,), (1.0, 2.0), beta=0.25)
