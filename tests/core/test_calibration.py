"""Sensor calibration by least squares against Desautel's published fit (section 2.3)."""

from __future__ import annotations

import pytest

from quadtank_tui.core.calibration import CalibrationError, SensorCalibration, fit_sensor


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
