"""Immutable pictures of the loop, published once per sample.

The UI renders the latest snapshot and the ring buffers; it never reaches into the
loop's state.  Everything here is a frozen value, safe to hand across threads.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from quadtank_tui.core.calibration.procedure import CalibrationStatus
from quadtank_tui.core.controllers.mpc.info import MPCInfo
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.backend import Levels4, Pair

if TYPE_CHECKING:  # scipy behind it; the loop process starts without it
    from quadtank_tui.core.controllers.statefb.quadtank import StateFeedbackInfo


@dataclass(frozen=True)
class LoopStats:
    """Timing of the loop.  jitter = actual minus scheduled start of a sample, s."""

    samples: int = 0
    #: samples that started late (their next slot had begun): at most `samples`
    overruns: int = 0
    #: sampling deadlines that passed without a sample (a late sample skips them):
    #: the speed held is the asked one x samples / (samples + skipped)
    skipped: int = 0
    jitter_last: float = 0.0
    jitter_max: float = 0.0
    #: 50th and 99th percentiles of |jitter| over the run, s (upper bin edges, at
    #: most 4.7 % above the true value: engine/jitter.py).
    jitter_p50: float = 0.0
    jitter_p99: float = 0.0
    #: Monotonic wall-clock time (time.monotonic) at which the last sample was taken;
    #: the UI shows its age so a user sees a stalled loop ("last sample 3.2 s ago").
    last_sample_wall: float = 0.0


@dataclass(frozen=True)
class LogStatus:
    """The Logging window's view of the logger."""

    active: bool = False        # LogOn and not yet complete
    rows: int = 0
    points: int = 0             # the points limit in force
    unsaved: bool = False       # rows exist that Save has not written to a .log
    file: str = ""              # the name it will be saved under (without .log)
    saved_path: str = ""        # the last .log written
    started_as: str = ""        # the name the unsaved log was started under

    @property
    def progress(self) -> float:
        """Fraction 0..1 of the points collected."""
        return 0.0 if self.points <= 0 else min(1.0, self.rows / self.points)


@dataclass(frozen=True)
class Snapshot:
    """The state of everything at sample `k` (process time `t`, seconds).

    y : levels y1..y4, normalized;  u : applied (saturated) pump inputs u1, u2;
    w : the two generator values;   r : references r1, r2 (equal to w in Automatic;
    in Manual the measured y1, y2 the controllers track).
    """

    t: float
    k: int
    y: Levels4
    u: Pair
    w: Pair
    r: Pair
    operation: str             # "Simul" | "Active"
    state: str                 # "Run" | "Pause"
    control: str               # "Manual" | "Automatic"
    params: Parameters         # the parameters in force
    speed: float               # Simul speed factor (1 = real time)
    realtime: bool             # a real-time clock (False: virtual)
    active_available: bool     # a DAQ backend is configured
    backend: str               # one line, e.g. "simulator", "modbus 127.0.0.1:5020"
    log: LogStatus
    stats: LoopStats
    fault: str | None = None   # why the loop paused itself (backend error, interlock)
    alarms: tuple[str, ...] = ()
    faults: str = ""           # injected faults acting on the simulation (core.faults), for the status line
    #: The disturbance pumps' duties d1, d2 (0..1) of the process in use; None: it has none.
    disturbances: tuple[float, float] | None = None
    #: The state feedback's gains, poles and delta while it is the controller type.
    statefb: StateFeedbackInfo | None = None
    #: The MPC's horizons, solve counts, faults and solve times while it is the controller type.
    mpc: MPCInfo | None = None
    #: The calibration procedure on the rig, while one runs or its last result is shown.
    calibration: CalibrationStatus | None = None
    #: Process time of the switch to Automatic the loop is in (None: in Manual): where an
    #: attempt at an exercise starts (app/exercise.py), exact whatever the screen's refresh.
    automatic_since: float | None = None
