"""Wave generators for the two input/reference channels (Nunes 1998, 5.3-5.4).

value = mean + amplitude * w, w in [-1, 1].  Square: the sign of a sine of the
given period.  Sine.  PRBS: a maximal-length sequence whose level is held for
`period` samples between possible changes (the original's meaning of Period for
PRBS), seeded so runs are reproducible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import Enum

from quadtank_tui.core.ranges import ParameterError, check_number, check_range, check_sampling_time


class Wave(str, Enum):
    """Wave types, spelled as in the `.par` file's `Wave` key."""

    SQUARE = "Square"
    SINE = "Sine"
    PRBS = "PRBS"


# An enum member is looked up through a descriptor in Python 3.11 (60 ns, a few
# times a sample): the every-sample methods compare with these names instead.
_PRBS, _SINE = Wave.PRBS, Wave.SINE

MEAN_MIN, MEAN_MAX = -1.0, 2.0  # the range WaveParams accepts for Mean


@dataclass(frozen=True)
class WaveParams:
    """One generator's settings, normalized units (fraction of 10 V).

    period : seconds for Square/Sine; samples between possible changes for PRBS.
    on : False gives a constant at the mean.
    seed : PRBS seed, any value in [0, 2^31); mixed into the register start (mixed_seed).
    """

    wave: Wave = Wave.SQUARE
    mean: float = 0.30
    amplitude: float = 0.0
    period: float = 60.0
    on: bool = False
    seed: int = 1

    def __post_init__(self) -> None:
        if not isinstance(self.wave, Wave):
            try:
                object.__setattr__(self, "wave", Wave(self.wave))
            except ValueError:
                raise ParameterError("Wave", f"must be Square, Sine or PRBS, got {self.wave!r}") from None
        check_range("Mean", self.mean, MEAN_MIN, MEAN_MAX)
        check_range("Amplitude", self.amplitude, 0.0, 1.0)
        check_range("Period", self.period, 0.0, 1e6, lo_open=True)
        if not isinstance(self.on, bool):
            raise ParameterError("On", f"must be on/off, got {self.on!r}")
        check_number("Seed", self.seed)
        if int(self.seed) != self.seed or not 0 <= self.seed < 2**31:
            raise ParameterError("Seed", f"must be an integer in [0, 2^31), got {self.seed!r}")


#: Slowest rate (normalized units per second) at which :meth:`Generator.nudge` moves
#: the mean: full scale in 20 s, quick enough for a held key, slow enough not to kick
#: a loop (a step is what :meth:`Generator.set_mean` is for).
DEFAULT_RAMP_RATE = 0.05

#: The shortest Square/Sine period, in samples, that can be told apart from a constant.
MIN_SAMPLES_PER_PERIOD = 2

def check_period(params: WaveParams, h: float) -> None:
    """Refuse a period the sampling time ``h`` (s) cannot render.

    The rule, for every wave: one period must span at least two samples, or the
    sampled wave cannot alternate (the original silently produced a constant; we
    refuse, and the message names the shortest period allowed).
    Square and Sine: period (s) >= 2 h.  PRBS: `period` counts the samples each level
    is held, so the shortest PRBS cycle (one level, then the other) spans 2 x period
    samples; any whole number of samples >= 1 passes whatever h is (the same rule
    the `.par` reader applies).  Refused with the wave off too, so switching it on
    can never reveal a bad period.
    """
    check_sampling_time(h)
    if params.wave is Wave.PRBS:
        if params.period < 1 or params.period != int(params.period):
            raise ParameterError(
                "Period",
                f"a PRBS period is a whole number of samples; the shortest allowed is 1 sample, "
                f"got {params.period:g}",
            )
        return
    shortest = MIN_SAMPLES_PER_PERIOD * h
    if params.period < shortest * (1.0 - 1e-12):
        raise ParameterError(
            "Period",
            f"the shortest period allowed at sampling time {h:g} s is {shortest:g} s "
            f"({MIN_SAMPLES_PER_PERIOD} samples), got {params.period:g} s",
        )


class LFSR:
    """Fibonacci linear-feedback shift register, one output bit per clock.

    Default polynomial x^31 + x^28 + 1 (PRBS31): primitive, so any non-zero seed runs
    through all 2^31 - 1 states before repeating.  ``bits``/``tap`` select another
    primitive trinomial x^bits + x^tap + 1 (e.g. 7, 6 for PRBS7, whose 127-long cycle
    the tests check in full).
    """

    def __init__(self, seed: int, bits: int = 31, tap: int = 28) -> None:
        self._bits = bits
        self._tap = tap
        self._mask = (1 << bits) - 1
        self.state = (int(seed) & self._mask) or 1  # the all-zero state is a dead end

    def next_bit(self) -> int:
        """Clock once; the new bit is x^bits XOR x^tap of the old register."""
        s = self.state
        bit = ((s >> (self._bits - 1)) ^ (s >> (self._tap - 1))) & 1
        self.state = ((s << 1) | bit) & self._mask
        return bit


def mixed_seed(seed: int, bits: int = 31) -> int:
    """A well-mixed, non-zero register start for a user seed (SplitMix64 finalizer).

    Seeding the register with the raw number would start small seeds such as the
    default 1 on a long run of zeros (the single set bit needs 28 clocks to reach the
    feedback tap, and the register stays sparse long after): a PRBS held 10 samples
    would sit at -1 for minutes.  Mixing keeps "same seed, same sequence".
    """
    z = (int(seed) + 0x9E3779B97F4A7C15) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    z ^= z >> 31
    return (z & ((1 << bits) - 1)) or 1


class Generator:
    """One wave channel, sampled: :meth:`value` reads this sample, :meth:`advance`
    moves to the next (two calls rather than one ``step()`` so the engine and the UI
    can read the current value any number of times without consuming samples).

    value = mean + amplitude * w,  w in [-1, 1].

    * Square and Sine are evaluated at the *middle* of each sample interval,
      ``t_k + h/2``: the held staircase is then centred on the continuous wave (no
      half-sample lag from the hold) and a wave of exactly two samples per period
      alternates +-1 instead of being sampled at its zero crossings (which would make
      a 2h Sine a silent constant).  Square is +1 in the first half of each period and
      -1 in the second: the sign of the sine, with sign(0) = +1.
    * PRBS holds each level ``period`` samples; after each hold the LFSR (started
      from :func:`mixed_seed`) is clocked and its bit picks +1 or -1, so the level changes with probability 1/2
      at each possible change: runs last period, 2 period, ... samples with
      probabilities 1/2, 1/4, ... (mean run 2 period samples).
    * The phase is kept as seconds into the period (Square/Sine) or samples into the
      hold (PRBS); a change of mean, of parameters or of h leaves it where it is.
      Switching the wave on starts a fresh period (a full first half of a Square).
    """

    # Set by reset(), which __init__ calls (declared here for the type checker).
    _t: float
    _n: int
    _mean: float

    def __init__(self, params: WaveParams, h: float, *, ramp_rate: float = DEFAULT_RAMP_RATE) -> None:
        check_period(params, h)
        self._p = params
        self._h = float(h)
        self.ramp_rate = check_range("ramp_rate", ramp_rate, 0.0, None, lo_open=True)
        self._target = params.mean
        self.reset()  # phase 0, the PRBS from its seed, the mean at the target

    # --- reading ----------------------------------------------------------------------

    @property
    def params(self) -> WaveParams:
        """Current settings, with the mean as it is now (for saving to a file)."""
        return replace(self._p, mean=self._mean)

    @property
    def mean(self) -> float:
        """The mean in use this sample, normalized (moves towards :attr:`target`)."""
        return self._mean

    @property
    def target(self) -> float:
        """Where nudges have asked the mean to go."""
        return self._target

    @property
    def h(self) -> float:
        return self._h

    def wave_value(self) -> float:
        """w in [-1, 1] for the current sample (0 when off)."""
        p = self._p
        if not p.on:
            return 0.0
        if p.wave is _PRBS:
            return self._level
        # Rounded so a sample that falls exactly on a half period (odd samples per
        # period) lands on the same side whatever the float rounding of the phase.
        cycles = round(((self._t + 0.5 * self._h) / p.period) % 1.0, 12) % 1.0
        if p.wave is _SINE:
            return math.sin(2.0 * math.pi * cycles)
        return 1.0 if cycles < 0.5 else -1.0

    def value(self) -> float:
        """mean + amplitude * w for the current sample, normalized."""
        return self._mean + self._p.amplitude * self.wave_value()

    # --- time -------------------------------------------------------------------------

    def advance(self) -> None:
        """Move to the next sample: the phase by h, the mean one ramp step."""
        p = self._p
        if p.wave is _PRBS:
            self._n += 1
            if self._n >= p.period:  # (a whole number of samples: check_period)
                self._n = 0
                self._level = self._prbs_level()
        else:
            self._t = (self._t + self._h) % p.period
        if self._mean != self._target:
            self._ramp(1)
        else:  # at its target, the usual case: what _ramp(1) does there, without its call every sample
            self._mean = self._target

    def advance_by(self, k: int) -> None:
        """k samples at once, as k calls of :meth:`advance` (up to the rounding of the
        phase): a preview on a coarser grid (the MPC's prediction step) reads one
        value every k samples without stepping through the others."""
        p = self._p
        if p.wave is Wave.PRBS:
            self._n += k
            while self._n >= int(p.period):
                self._n -= int(p.period)
                self._level = self._prbs_level()
        else:
            self._t = (self._t + k * self._h) % p.period
        self._ramp(k)

    def _ramp(self, k: int) -> None:
        """The mean k ramp steps towards the target."""
        step = self.ramp_rate * self._h * k
        gap = self._target - self._mean
        self._mean = self._target if abs(gap) <= step else self._mean + math.copysign(step, gap)

    def take(self, n: int) -> list[float]:
        """The next `n` samples, as `n` rounds of :meth:`value` then :meth:`advance`.

        A PRBS at a steady mean is filled a hold at a time (its state is whole
        numbers, so this is exactly the sample-by-sample result); the batch studies
        generate millions of reference samples this way."""
        p = self._p
        out: list[float] = []
        if p.wave is not Wave.PRBS or self._mean != self._target:
            for _ in range(n):
                out.append(self.value())
                self.advance()
            return out
        period = int(p.period)
        while len(out) < n:
            chunk = min(period - self._n, n - len(out))
            out.extend([self.value()] * chunk)
            self._n += chunk
            if self._n >= period:
                self._n = 0
                self._level = self._prbs_level()
        return out

    def _prbs_level(self) -> float:
        return 1.0 if self._lfsr.next_bit() else -1.0

    # --- changes ----------------------------------------------------------------------

    def set_params(self, params: WaveParams) -> None:
        """New settings (mean as a step).  The phase is kept; a new seed restarts the
        PRBS register, a new wave type or switching on starts a fresh period."""
        check_period(params, self._h)
        old = self._p
        self._p = params
        self._mean = self._target = params.mean
        if params.seed != old.seed:
            self._lfsr = LFSR(mixed_seed(params.seed))
            self._level = self._prbs_level()
        if params.wave is not old.wave or (params.on and not old.on):
            self._t = 0.0
            self._n = 0
        if params.wave is not Wave.PRBS:
            self._t %= params.period

    def set_mean(self, mean: float) -> None:
        """Step the mean to a typed value (the wave keeps its phase)."""
        m = check_range("Mean", mean, MEAN_MIN, MEAN_MAX)
        self._mean = self._target = m

    def nudge(self, delta: float) -> None:
        """Move the mean progressively by ``delta``: the target moves now, the mean
        follows at :attr:`ramp_rate` per second as samples advance."""
        d = check_number("Mean", delta)
        self._target = min(MEAN_MAX, max(MEAN_MIN, self._target + d))

    def set_sampling_time(self, h: float) -> None:
        """New sampling time, s; refused (nothing changes) if the period gets too short.

        The phase is kept in seconds (Square/Sine) or samples (PRBS, whose period
        counts samples)."""
        check_period(self._p, h)
        self._h = float(h)

    def reset(self) -> None:
        """Restart the wave: phase 0 and the PRBS from its seed; the mean jumps to its
        target (a reset ends a ramp), so the same settings give the same samples."""
        self._t = 0.0  # seconds into the current period (Square/Sine)
        self._n = 0  # samples into the current hold (PRBS)
        self._lfsr = LFSR(mixed_seed(self._p.seed))
        self._level = self._prbs_level()
        self._mean = self._target
