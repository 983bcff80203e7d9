"""Wave generators: known sample values, the period rule, phase keeping, PRBS."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from hypothesis import given, settings, strategies as st

from quadtank_tui.core.controllers.signals import (
    LFSR, Generator, Wave, WaveParams, check_period,
)
from quadtank_tui.core.ranges import ParameterError


def samples(g: Generator, n: int) -> list[float]:
    out = []
    for _ in range(n):
        out.append(g.value())
        g.advance()
    return out


def test_off_is_the_mean() -> None:
    g = Generator(WaveParams(Wave.SINE, mean=0.3, amplitude=0.2, period=10.0, on=False), 1.0)
    assert samples(g, 25) == [0.3] * 25


def test_square_known_values() -> None:
    g = Generator(WaveParams(Wave.SQUARE, mean=0.3, amplitude=0.1, period=4.0, on=True), 1.0)
    assert samples(g, 8) == pytest.approx([0.4, 0.4, 0.2, 0.2] * 2)


def test_sine_known_values_at_mid_interval() -> None:
    g = Generator(WaveParams(Wave.SINE, mean=0.5, amplitude=0.2, period=8.0, on=True), 1.0)
    want = [0.5 + 0.2 * math.sin(2 * math.pi * (k + 0.5) / 8) for k in range(16)]
    assert samples(g, 16) == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize("wave", [Wave.SQUARE, Wave.SINE])
def test_two_samples_per_period_alternates_not_constant(wave: Wave) -> None:
    g = Generator(WaveParams(wave, mean=0.3, amplitude=0.1, period=0.2, on=True), 0.1)
    assert samples(g, 6) == pytest.approx([0.4, 0.2] * 3, abs=1e-12)


def test_period_under_two_samples_is_refused_with_the_shortest_allowed() -> None:
    with pytest.raises(ParameterError) as err:
        check_period(WaveParams(Wave.SQUARE, period=0.15, on=True), 0.1)
    assert err.value.field == "Period"
    assert "shortest period allowed at sampling time 0.1 s is 0.2 s" in str(err.value)
    check_period(WaveParams(Wave.SINE, period=0.2), 0.1)  # exactly two samples is fine


def test_prbs_period_is_a_whole_number_of_samples() -> None:
    for bad in (0.5, 2.5):
        with pytest.raises(ParameterError) as err:
            Generator(WaveParams(Wave.PRBS, period=bad, on=True), 1.0)
        assert err.value.field == "Period" and "shortest allowed is 1 sample" in str(err.value)
    check_period(WaveParams(Wave.PRBS, period=1), 5.0)  # counts samples, whatever h is
    x = samples(Generator(WaveParams(Wave.PRBS, mean=0.0, amplitude=1.0, period=1, on=True), 5.0), 64)
    # A change is possible every sample, and the default seed 1 does not start on the
    # raw register's long run of zeros (mixed_seed).
    assert 20 < sum(a != b for a, b in zip(x, x[1:])) < 44


def test_sampling_time_change_that_shortens_the_period_too_much_is_refused() -> None:
    g = Generator(WaveParams(Wave.SQUARE, period=4.0, on=True), 1.0)
    with pytest.raises(ParameterError, match="shortest period allowed at sampling time 3 s is 6 s"):
        g.set_sampling_time(3.0)
    assert g.h == 1.0


def test_step_mean_keeps_phase() -> None:
    p = WaveParams(Wave.SQUARE, mean=0.3, amplitude=0.1, period=4.0, on=True)
    g = Generator(p, 1.0)
    first = samples(g, 3)
    g.set_mean(0.5)
    assert first + samples(g, 5) == pytest.approx([0.4, 0.4, 0.2, 0.4, 0.6, 0.6, 0.4, 0.4])


def test_nudge_ramps_at_the_rate_limit_and_keeps_phase() -> None:
    g = Generator(WaveParams(Wave.SQUARE, mean=0.3, amplitude=0.1, period=4.0, on=True), 0.5,
                  ramp_rate=0.05)
    g.nudge(0.1)
    g.nudge(-0.02)
    assert g.target == pytest.approx(0.38)
    means = []
    for _ in range(5):
        means.append(g.mean)
        g.advance()
    assert means == pytest.approx([0.3, 0.325, 0.35, 0.375, 0.38])
    assert g.value() == pytest.approx(0.38 - 0.1)  # t = 2.5 s: second half of the period


def test_sampling_time_change_keeps_phase_in_seconds() -> None:
    g = Generator(WaveParams(Wave.SQUARE, mean=0.0, amplitude=1.0, period=4.0, on=True), 1.0)
    g.advance()  # t = 1 s
    g.set_sampling_time(0.5)
    assert samples(g, 6) == [1.0, 1.0, -1.0, -1.0, -1.0, -1.0]  # mid-points 1.25 .. 3.75 s


def test_set_params_keeps_phase_and_switching_on_restarts_it() -> None:
    p = WaveParams(Wave.SQUARE, mean=0.0, amplitude=1.0, period=4.0, on=True)
    g = Generator(p, 1.0)
    samples(g, 3)
    g.set_params(replace(p, amplitude=0.5))
    assert samples(g, 2) == [-0.5, 0.5]  # t = 3 s, then 0 s of the next period
    g.set_params(replace(p, on=False))
    samples(g, 3)
    g.set_params(p)
    assert samples(g, 3) == [1.0, 1.0, -1.0]


def test_lfsr_is_maximal_length() -> None:
    # The same shift-register code with the primitive trinomial x^7 + x^6 + 1 must
    # visit all 127 non-zero states before repeating.
    reg = LFSR(seed=1, bits=7, tap=6)
    seen = set()
    for _ in range(127):
        seen.add(reg.state)
        reg.next_bit()
    assert len(seen) == 127 and reg.state == 1


def prbs(seed: int, period: int, n: int) -> list[float]:
    return samples(Generator(WaveParams(Wave.PRBS, mean=0.0, amplitude=1.0, period=period,
                                        on=True, seed=seed), 0.1), n)


def test_same_seed_same_prbs_and_reset_replays_it() -> None:
    a = prbs(12345, 3, 300)
    assert a == prbs(12345, 3, 300)
    assert a != prbs(54321, 3, 300)
    g = Generator(WaveParams(Wave.PRBS, amplitude=1.0, mean=0.0, period=3, on=True, seed=12345), 0.1)
    samples(g, 17)
    g.reset()
    assert samples(g, 300) == a


def test_long_prbs_statistics_match_the_definition() -> None:
    period = 4
    x = prbs(2024, period, 200_000)
    assert set(x) == {-1.0, 1.0}
    assert abs(sum(x) / len(x)) < 0.02
    changes = [k for k in range(1, len(x)) if x[k] != x[k - 1]]
    assert all(k % period == 0 for k in changes)  # only at the end of a hold
    runs = [b - a for a, b in zip(changes, changes[1:])]
    assert min(runs) == period
    # A change at each possible change point with probability 1/2: runs are geometric
    # in units of `period`, mean 2 * period samples.
    assert sum(runs) / len(runs) == pytest.approx(2 * period, rel=0.03)
    assert runs.count(period) / len(runs) == pytest.approx(0.5, abs=0.02)


@settings(max_examples=60, deadline=None)
@given(
    wave=st.sampled_from(list(Wave)),
    mean=st.floats(-1.0, 2.0),
    amplitude=st.floats(0.0, 1.0),
    samples_per_period=st.floats(1.0, 50.0),
    h=st.floats(0.05, 5.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_value_stays_within_mean_plus_minus_amplitude(
    wave: Wave, mean: float, amplitude: float, samples_per_period: float, h: float, seed: int
) -> None:
    period = round(samples_per_period) if wave is Wave.PRBS else (1 + samples_per_period) * h
    g = Generator(WaveParams(wave, mean, amplitude, period, True, seed), h)
    for v in samples(g, 40):
        assert mean - amplitude - 1e-12 <= v <= mean + amplitude + 1e-12


@pytest.mark.parametrize("wave, period", [(Wave.PRBS, 7), (Wave.PRBS, 1), (Wave.SQUARE, 3.0), (Wave.SINE, 2.5)])
def test_take_is_value_then_advance_n_times(wave: Wave, period: float) -> None:
    params = WaveParams(wave=wave, mean=0.4, amplitude=0.1, period=period, on=True, seed=11)
    one, many = Generator(params, 0.5), Generator(params, 0.5)
    expected = []
    for _ in range(1000):
        expected.append(one.value())
        one.advance()
    assert many.take(3) + many.take(997) == expected
    assert many.value() == one.value()
    one.nudge(0.2)
    many.nudge(0.2)
    ramped = []
    for _ in range(50):  # a ramping mean takes the sample-by-sample path
        ramped.append(one.value())
        one.advance()
    assert many.take(50) == ramped
