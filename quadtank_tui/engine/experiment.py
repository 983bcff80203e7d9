"""Headless experiments: a script's events applied at their times, then a summary.

The same engine as the TUI, stepped without a thread: events whose time has come
are submitted before the sample, in file order for equal times, and the run lasts
`duration` seconds of loop time (the sum of the sampling periods, paused or not, so
a script that pauses still ends).  A refused event stops the run with an error that
names the script, the event and its line; the log so far is kept.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from typing import Callable

from quadtank_tui.core.metrics import LoopMetrics, loop_metrics
from quadtank_tui.engine.commands import (
    AddWater, Command, LogOff, LogOn, SetControlMode, SetDisturbance, SetFault, SetParams, SetState,
)
from quadtank_tui.engine.inputs_from import replay_events
from quadtank_tui.engine.runner import Engine, LoopTime
from quadtank_tui.files.script import Event, Script


@dataclass(frozen=True)
class Summary:
    """What `quadtank run` prints: per loop figures over the Automatic window."""

    duration: float
    samples: int
    overruns: int                      # samples that started late (<= samples)
    skipped: int                       # sampling slots that passed without a sample
    jitter_max: float
    jitter_p99: float
    control: str
    window: float | None              # seconds of Automatic measured (None: Manual)
    loops: tuple[LoopMetrics, ...]     # empty in Manual
    final_y: tuple[float, float]
    final_u: tuple[float, float]
    fault: str | None
    #: the speed factor asked of a paced virtual clock (None: real time or unpaced)
    speed: float | None = None
    #: slots the last sample was late by (a virtual clock's lag not made up yet: engine/clock.py)
    behind: int = 0

    @property
    def speed_held(self) -> float | None:
        """The speed the run kept, on the wall's time: every slot that went by was
        sampled, skipped, or is still to be made up at the end (behind), so asked x
        samples / (samples + skipped + behind)."""
        slots = self.samples + self.skipped + self.behind
        if self.speed is None or slots == 0:
            return None
        return self.speed * self.samples / slots


def event_commands(event: Event, engine: Engine) -> list[Command]:
    """The commands one event stands for, given the parameters in force now."""
    a, v = event.action, event.value
    if a == "mode":
        return [SetControlMode(v)]
    if a == "state":
        return [SetState(v)]
    if a == "set":
        return [SetParams(dict(v))]
    if a == "step":
        params = engine.snapshot().params
        return [SetParams({k: params.get(k) + d for k, d in v.items()})]
    if a == "add_water":
        return [AddWater(*v)]
    if a == "log":
        return [LogOn() if v == "on" else LogOff()]
    if a == "fault":
        return [SetFault(*v)]
    if a == "disturbance":
        return [SetDisturbance(*v)]
    raise ValueError(f"unknown action {a!r}")


def run_experiment(engine: Engine, script: Script | None, duration: float,
                   watch: Callable[[LoopTime], None] | None = None) -> int:
    """Run `duration` s of loop time applying the script's events; returns samples.
    `watch(elapsed)` runs ahead of every sample too (what it raises ends the run)."""
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds, got {duration!r}")
    events = collections.deque(script.events if script else ())
    name = script.file if script else ""
    if not events:  # nothing to apply: no call ahead of every sample but the watch
        return engine.run_for(duration, before=watch)

    def before(elapsed: LoopTime) -> None:
        if watch is not None:
            watch(elapsed)
        apply_due(engine, events, elapsed, name)
    return engine.run_for(duration, before=before)


def apply_due(engine: Engine, events: collections.deque[Event], elapsed: LoopTime, name: str) -> None:
    """Apply (and drop) the script's events due at `elapsed` loop time; a refused
    command is the script's error, naming its file and line."""
    while events and elapsed.reached(events[0].at):
        event = events.popleft()
        if event.action == "inputs_from":  # one event per row of the log, from now on
            merged = sorted([*events, *replay_events(engine, event, name)], key=lambda e: e.at)
            events.clear()
            events.extend(merged)
            continue
        _apply(engine, event, name)


def _apply(engine: Engine, event: Event, name: str) -> None:
    for command in event_commands(event, engine):
        result = engine.submit(command).result()
        if not result.ok:
            raise event.where(name, result.message)


def summarize(engine: Engine, duration: float) -> Summary:
    """Final error, overshoot, settling time and IAE of both loops since Automatic
    began (within what the ring buffers hold), and the loop's timing."""
    loop = engine.loop
    snap = engine.snapshot()
    loops: tuple[LoopMetrics, ...] = ()
    window = None
    if loop.automatic_since is not None:
        hist = engine.history()
        keep = hist["t"] >= loop.automatic_since - 1e-9
        t = hist["t"][keep]
        if t.size:
            window = float(t[-1] - t[0] + loop.h)
            loops = tuple(loop_metrics(t, hist[f"y{i}"][keep], hist[f"ref{i}"][keep]) for i in (1, 2))
    paced = not snap.realtime and math.isfinite(snap.speed)
    return Summary(duration, snap.stats.samples, snap.stats.overruns, snap.stats.skipped, snap.stats.jitter_max,
                   snap.stats.jitter_p99, snap.control, window, loops, (snap.y[0], snap.y[1]), snap.u, snap.fault,
                   speed=snap.speed if paced else None, behind=engine.clock.behind if paced else 0)


def format_summary(s: Summary) -> str:
    """One screen of text."""
    skipped = f" ({s.skipped} sampling slots skipped)" if s.skipped else ""
    lines = [
        f"ran {s.duration:g} s: {s.samples} samples, {s.overruns} overruns{skipped}, "
        f"|jitter| p99 {s.jitter_p99 * 1000:.2f} ms, max {s.jitter_max * 1000:.2f} ms",
    ]
    held = s.speed_held
    if s.speed is not None and held is not None:
        lines.append(f"speed      x{s.speed:g} asked, x{held:.3g} held")
    lines += [
        f"final      y1 {s.final_y[0]:.4f}  y2 {s.final_y[1]:.4f}   u1 {s.final_u[0]:.4f}  u2 {s.final_u[1]:.4f}",
    ]
    if s.fault:
        lines.append(f"FAULT      {s.fault}")
    if not s.loops:
        lines.append(f"control    {s.control}: no loop to measure (the figures need Automatic)")
        return "\n".join(lines)
    lines.append(f"loops      measured over the last {s.window:g} s in Automatic (2 % band)")
    lines.append("loop  final error   overshoot   settling      IAE      last step")
    for i, m in enumerate(s.loops, start=1):
        over = "-" if m.overshoot is None else f"{m.overshoot:.1f} %"
        if m.step is None:
            settle, step = "-", "none"
        else:
            settle = "not settled" if m.settling_time is None else f"{m.settling_time:.0f} s"
            step = f"{m.step:+.3f} at {m.step_time:g} s"
        lines.append(f"{i:>4}  {m.final_error:+11.5f}  {over:>10}  {settle:>11}  {m.iae:8.3f}  {step}")
    return "\n".join(lines)

