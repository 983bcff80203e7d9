"""The steady-state calibration procedure as a state machine (Desautel 2.3; B9).

For each pump voltage the pumps are held until every sensor voltage stays within
`tol` volts over the last `window` reads; then the operator reads the heights on
the tanks' scales, and the next voltage follows.  Pure: it is fed the reads and
says what the pumps get, so the control loop can run it one sample at a time on a
real process (engine/calibration_step.py) and `quadtank daq calibrate` in a plain
loop paced by sleeps (daq/calibrate.run_procedure), and a test can drive it with
numbers.

Phases: settling -> heights -> settling (next voltage) ... -> done; or failed (the
sensors did not settle in time) or cancelled.  Outside settling and heights the
pumps are at 0.

Example
-------
>>> run = CalibrationRun((2.0,), SettleRule(window=3, tol=0.01, timeout=60.0), h=1.0)
>>> [run.pumps(), run.feed((1.0, 1.0, 0.5, 0.5)), run.feed((1.0, 1.0, 0.5, 0.5))]
[(2.0, 2.0), 'settling', 'settling']
>>> run.feed((1.005, 1.0, 0.5, 0.5)), run.settled
('heights', (1.0016666666666667, 1.0, 0.5, 0.5))
>>> run.heights((5.0, 5.1, 2.0, 2.1)); run.phase, run.pumps(), run.columns["level2"]
('done', (0.0, 0.0), [5.1])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

from quadtank_tui.core.calibration.fits import CalibrationError

SETTLING, HEIGHTS, DONE, FAILED, CANCELLED = "settling", "heights", "done", "failed", "cancelled"


@dataclass(frozen=True)
class SettleRule:
    """Settled: `window` reads all within `tol` V; give up after `timeout` s at one
    voltage."""

    window: int = 30
    tol: float = 0.004
    timeout: float = 3600.0

    def __post_init__(self) -> None:
        if not (isinstance(self.window, int) and self.window >= 2):
            raise CalibrationError(f"the settling window must be >= 2 reads, got {self.window!r}")
        for name in ("tol", "timeout"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise CalibrationError(f"{name} must be a number > 0, got {value!r}")


@dataclass
class SettleWindow:
    """The last `rule.window` reads and whether they agree within `rule.tol`."""

    rule: SettleRule
    reads: list[tuple[float, ...]] = field(default_factory=list)

    def add(self, read: Sequence[float]) -> tuple[float, ...] | None:
        """Take a read; the window's mean once it is full and flat, else None."""
        self.reads = (self.reads + [tuple(float(v) for v in read)])[-self.rule.window:]
        if len(self.reads) == self.rule.window and self.spread() <= self.rule.tol:
            n = len(self.reads)
            return tuple(sum(r[i] for r in self.reads) / n for i in range(len(self.reads[0])))
        return None

    def spread(self) -> float:
        """The largest sensor's max - min over the window, V."""
        if not self.reads:
            return math.inf
        return max(max(r[i] for r in self.reads) - min(r[i] for r in self.reads)
                   for i in range(len(self.reads[0])))


class CalibrationRun:
    """The procedure at `volts` (each held on every pump of the plant), one read per
    sample of `h` seconds, `tanks` sensors."""

    def __init__(self, volts: Sequence[float], rule: SettleRule, h: float, tanks: int = 4, pumps: int = 2) -> None:
        if not volts:
            raise CalibrationError("give at least one pump voltage (two or more for a gain and an offset)")
        if any(not (isinstance(v, (int, float)) and 0.0 <= v <= 10.0) for v in volts):
            raise CalibrationError("pump voltages must be within 0..10 V")
        self.volts = tuple(float(v) for v in volts)
        self.rule = rule
        self.h = float(h)
        self.tanks = tanks
        #: Pumps the plant has: a one-pump rig's u2 stays 0 (and is not in the pairs).
        self.pumps_used = pumps
        self.step = 0
        self.phase = SETTLING
        self.elapsed = 0.0
        self.message = ""
        self.settled: tuple[float, ...] = ()
        self.columns: dict[str, list[float]] = {}
        self._window = SettleWindow(rule)

    @property
    def active(self) -> bool:
        """Whether the pumps are being held (settling or waiting for heights)."""
        return self.phase in (SETTLING, HEIGHTS)

    def pumps(self) -> tuple[float, float]:
        """The pump voltages now (0 outside settling and heights)."""
        v = self.volts[self.step] if self.active else 0.0
        return (v, v)

    def spread(self) -> float:
        return self._window.spread()

    def reads(self) -> int:
        return len(self._window.reads)

    def feed(self, volts: Sequence[float], dt: float | None = None) -> str:
        """One read of the sensors (V) while settling, `dt` s after the one before
        (default: a sample, `h`; a procedure paced by sleeps passes what its clock
        measured); the phase after it."""
        if self.phase != SETTLING:
            return self.phase
        self.elapsed += self.h if dt is None else dt
        mean = self._window.add(volts[: self.tanks])
        if mean is not None:
            self.settled, self.phase = mean, HEIGHTS
        elif self.elapsed > self.rule.timeout:
            self.fail(f"the sensors did not settle within {self.rule.timeout:g} s at {self.volts[self.step]:g} V "
                      f"(spread {self.spread():.4f} V > {self.rule.tol:g} V)")
        return self.phase

    def heights(self, levels: Sequence[float]) -> None:
        """The heights read on the scales (cm) for the settled state; then the next
        voltage, or done.  CalibrationError (nothing changes) if they are not
        `tanks` numbers >= 0 or no state is waiting for them."""
        if self.phase != HEIGHTS:
            raise CalibrationError("no settled state is waiting for heights")
        h = [float(x) for x in levels]
        if len(h) != self.tanks or not all(math.isfinite(x) and x >= 0 for x in h):
            raise CalibrationError(f"give {self.tanks} heights >= 0 cm, one per tank")
        v = self.volts[self.step]
        row = {**{f"u{j + 1}": v for j in range(self.pumps_used)}, **{f"volts{i + 1}": self.settled[i] for i in range(self.tanks)},
               **{f"level{i + 1}": h[i] for i in range(self.tanks)}}
        for k, x in row.items():
            self.columns.setdefault(k, []).append(x)
        self.step += 1
        self.settled = ()
        self.elapsed = 0.0
        self._window = SettleWindow(self.rule)
        self.phase = SETTLING if self.step < len(self.volts) else DONE

    def fail(self, why: str) -> None:
        self.phase, self.message = FAILED, why

    def cancel(self) -> None:
        if self.active:
            self.phase, self.message = CANCELLED, "cancelled: pumps at 0"


@dataclass(frozen=True)
class CalibrationStatus:
    """What a calibration window shows: the phase, where the procedure is, the pairs
    so far (columns as in a pairs file: u1 u2 volts1.. level1..), and where its
    result belongs (the DAQ configuration file, the parameter folder)."""

    phase: str
    volts: tuple[float, ...]
    step: int
    reads: int
    window: int
    spread: float
    elapsed: float
    settled: tuple[float, ...]
    columns: tuple[tuple[str, tuple[float, ...]], ...]
    message: str = ""
    tanks: int = 4
    daq_file: str = ""
    par_dir: str = ""

    @classmethod
    def of(cls, run: CalibrationRun, *, daq_file: str = "", par_dir: str = "") -> CalibrationStatus:
        return cls(run.phase, run.volts, run.step, run.reads(), run.rule.window, run.spread(), run.elapsed,
                   run.settled, tuple((k, tuple(v)) for k, v in run.columns.items()), run.message,
                   run.tanks, daq_file, par_dir)
