"""What the user chooses for the model predictive controller (the `MPC` settings).

Horizon         prediction horizon N, prediction steps
Step            prediction step, s: the model predicts, and the planned input moves,
                on this grid (rounded to a whole number of sampling times; 0: the
                sampling time); the estimator and the solve still run every sample
ControlHorizon  prediction steps over which the input may move; after it the input
                is held (0: the whole horizon)
OutputWeight    weight on each tracked level, per (level / tank height)^2
InputWeight     weight on each pump's distance from its target, per (V / pump range)^2
RateWeight      weight on each pump's change per sample, per (V / pump range)^2
RateLimit       largest pump change, V/s (0: none)
LevelMargin     cm below each tank's brim where the soft level limit sits
Preview         1: the future reference (a wave, a script) is used over the horizon
Disturbance     "input" (a constant error at each pump, plus a level offset on each
                measured tank beyond the pump count) or "output" (a level offset on
                every measured tank): what the estimator absorbs so tracking is offset-free
Measured        the levels the Kalman filter reads: "all", or tank numbers from 1
                ("1 2": some rigs measure only the lower tanks)
SlackWeight     price of a level limit violation, per (level / tank height)

The weights are relative to the signals' ranges so one set of numbers means the same
on a 20 cm quadruple tank and a 0.3 m two-tank rig.
"""

from __future__ import annotations

from dataclasses import dataclass

from quadtank_tui.core.ranges import ParameterError, check_range

SECTION = "MPC"
DISTURBANCE_MODELS = ("input", "output")


ALL = "all"


def parse_measured(text: str, key: str = "Measured") -> tuple[int, ...]:
    """1-based tank numbers from text like "1 2" (sorted, no repeats); () for "all"."""
    words = text.replace(",", " ").split()
    if len(words) == 1 and words[0].lower() == ALL:
        return ()
    try:
        tanks = sorted({int(w) for w in words})
    except ValueError:
        raise ParameterError(key, f"{text!r} is not a list of tank numbers (write 1 2 3 4)") from None
    if not tanks or tanks[0] < 1:
        raise ParameterError(key, f"name at least one tank, numbered from 1, got {text!r}")
    return tuple(tanks)


@dataclass(frozen=True)
class MPCSettings:
    """The MPC settings (see the module docstring); validated here."""

    horizon: int = 30
    control_horizon: int = 0
    output_weight: float = 1.0
    input_weight: float = 0.01
    rate_weight: float = 0.0
    rate_limit: float = 0.0
    level_margin: float = 1.0
    preview: bool = True
    disturbance: str = "input"
    measured: str = ALL
    slack_weight: float = 1e3
    step: float = 0.0

    def __post_init__(self) -> None:
        for key, value, lo, hi in (("Horizon", self.horizon, 1, 1000), ("ControlHorizon", self.control_horizon, 0, 1000)):
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
                raise ParameterError(key, f"must be a whole number in {lo}..{hi}, got {value!r}")
        if self.control_horizon > self.horizon:
            raise ParameterError("ControlHorizon",
                                 f"{self.control_horizon} is longer than the horizon ({self.horizon})")
        check_range("OutputWeight", self.output_weight, 0.0, 1e6, lo_open=True)
        check_range("InputWeight", self.input_weight, 0.0, 1e6, lo_open=True)
        check_range("RateWeight", self.rate_weight, 0.0, 1e6)
        check_range("RateLimit", self.rate_limit, 0.0, 1e3)
        check_range("LevelMargin", self.level_margin, 0.0, 50.0)
        check_range("SlackWeight", self.slack_weight, 0.0, 1e9, lo_open=True)
        check_range("Step", self.step, 0.0, 600.0)
        if not isinstance(self.preview, bool):
            raise ParameterError("Preview", "must be 0 or 1")
        if self.disturbance not in DISTURBANCE_MODELS:
            raise ParameterError("Disturbance",
                                 f"must be one of {', '.join(DISTURBANCE_MODELS)}, got {self.disturbance!r}")
        if not isinstance(self.measured, str):
            raise ParameterError("Measured", f"must be text, got {self.measured!r}")
        parse_measured(self.measured)

    @property
    def moves(self) -> int:
        """Samples over which the input moves (the control horizon, or N)."""
        return self.control_horizon or self.horizon

    def step_samples(self, T: float) -> int:
        """Sampling times per prediction step at sampling time T s (at least one)."""
        return max(1, int(round(self.step / T))) if self.step > 0 else 1

    def measured_states(self, tanks: int) -> tuple[int, ...]:
        """The measured levels, 0-based, on a plant of `tanks` tanks."""
        return tuple(t - 1 for t in parse_measured(self.measured)) or tuple(range(tanks))

    def check_plant(self, kind: str, tanks: int, tracked: tuple[int, ...], pumps: int) -> tuple[int, ...]:
        """The measured levels (0-based) on a plant of `kind` with `tanks` tanks, the
        `tracked` ones (0-based) and `pumps` inputs; ParameterError (MPC.Measured or
        MPC.Disturbance) when the estimator cannot work with them.  Plain counting,
        so a window checks it before anything is designed."""
        measured = self.measured_states(tanks)
        if measured[-1] >= tanks:
            raise ParameterError(f"{SECTION}.Measured", f"the {kind} plant has {tanks} tanks, got tank {measured[-1] + 1}")
        missing = [t + 1 for t in tracked if t not in measured]
        if missing:
            raise ParameterError(f"{SECTION}.Measured", f"tracked tank(s) {missing} must be measured")
        if len(tracked) != pumps:
            raise ParameterError(f"{SECTION}.Measured", f"{len(tracked)} tracked levels need as many pumps, got {pumps}")
        if self.disturbance == "input" and len(measured) < pumps:
            raise ParameterError(f"{SECTION}.Disturbance",
                                 f"input disturbances need {pumps} measured levels, got {len(measured)}")
        return measured
