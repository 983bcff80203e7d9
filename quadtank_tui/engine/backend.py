"""The one small interface every process backend implements (style.md habit 4).

Four levels in, two pump inputs out, all in normalized units (a fraction of 10 V).
The in-process simulator and the DAQ drivers (Modbus TCP, ...) sit behind it; the
engine never knows which one it talks to beyond `kind`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant

Levels4 = tuple[float, float, float, float]
Pair = tuple[float, float]


class BackendError(Exception):
    """An I/O fault of the process link; the message is shown to the user as the
    reason the engine paused (e.g. "read of AIN0 timed out after 2 tries")."""


@dataclass(frozen=True)
class InterlockHold:
    """One tank above its level limit at a write, and the pumps (1-based) its trip
    held at 0 whatever the controller asked; `alarm` is the line the user sees."""

    tank: int
    pumps: tuple[int, ...]
    alarm: str


class ProcessBackend(ABC):
    """A process the loop reads and drives.

    Contract for implementers:
    - `read_levels` and `write_pumps` raise only BackendError (anything else is a bug
      and the engine treats it the same way: pumps to 0, Pause, reason shown).
    - `safe_state` commands the pumps to 0 and never raises: it is called on Pause,
      Reset, Exit, Ctrl-C and after any fault, possibly on a dead link.
    - `elapse(dt)` lets dt seconds of process time pass.  The simulator integrates
      its model; a real process ignores it (its time passes by itself).
    """

    #: "Simul" for the simulator, "Active" for a real (or virtual-rig) process.
    kind: str = "Simul"
    #: One line for the status bar, e.g. "simulator" or "modbus 127.0.0.1:5020".
    description: str = ""
    #: Why the last `safe_state` could not be confirmed ("" when it was; a write of
    #: the pumps that succeeds clears it): the pumps may still run.  Meanwhile the
    #: backend must not keep the rig's own protection (`safety_net`) quiet: the
    #: paused loop retries `safe_state` and reads nothing, and `close` disarms nothing.
    safe_state_error: str = ""
    #: What stops the pumps when this program cannot (said with safe_state_error).
    safety_net: str = "the rig's own watchdog"

    @abstractmethod
    def read_levels(self) -> Levels4:
        """y1..y4, normalized."""

    @abstractmethod
    def write_pumps(self, u: Pair) -> None:
        """Apply u1, u2 (normalized, already saturated to [0, 1])."""

    @abstractmethod
    def safe_state(self) -> None:
        """Pumps to 0; must not raise."""

    def written(self, requested: Pair) -> Pair:
        """The pump inputs the last `write_pumps(requested)` really wrote: what the
        log, the trends and the controllers' anti-windup must see (an interlock may
        have cut some to 0)."""
        return requested

    def interlock_holds(self) -> tuple[InterlockHold, ...]:
        """The tanks whose interlock trip held pumps at 0 at the last write (none
        without an interlock)."""
        return ()

    def plant_refused(self, plant: Plant) -> str | None:
        """Why this process cannot be `plant` (a DAQ wired for another rig), or None.
        The simulator becomes any plant."""
        return None

    def arm(self, tsamp: float) -> None:
        """Active control on this process starts, or its sampling time changed: a
        DAQ arms its device's watchdog for a few samples of `tsamp` and has the rig
        watched should this program die (daq/modbus.py).  Nothing for the simulator."""

    def elapse(self, dt: float) -> None:
        """Let `dt` s of process time pass (only the simulator acts on it)."""

    def close(self) -> None:
        """Release the link.  With `safe_state_error` set (the pumps not confirmed at
        0), leave the rig's protection to stop them: disarm nothing."""


def unconfirmed_stop(backend: ProcessBackend | None) -> str:
    """"pumps NOT confirmed at 0 (...): why" while `backend`'s last safe_state could
    not be confirmed, else "" (the one wording of the snapshot, the summary and a
    session's end)."""
    error = getattr(backend, "safe_state_error", "")  # (a test's stand-in may be no ProcessBackend)
    if not error:
        return ""
    net = getattr(backend, "safety_net", ProcessBackend.safety_net)
    return f"pumps NOT confirmed at 0 (left to {net} to stop them): {error}"


def arm(backend: ProcessBackend, tsamp: float) -> None:
    """`backend.arm(tsamp)` (a backend written before the hook, or a test's stand-in, may not have one)."""
    hook = getattr(backend, "arm", None)
    if hook is not None:
        hook(tsamp)


def identity_refused(daq: ProcessBackend) -> str | None:
    """Why Active control must not start on `daq`: the rig says it is another than
    its DAQ file (daq/identity.py), one line; None when it agrees, says nothing of
    itself, or the backend cannot be asked (a test's stand-in)."""
    ask = getattr(daq, "identity_refused", None)
    return ask() if ask is not None else None


def plant_refused(daq: ProcessBackend | None, plant: Plant) -> str | None:
    """Why the DAQ cannot be `plant` (wired for another rig), or None; a backend
    without the question (a test's stand-in) takes any plant."""
    ask = getattr(daq, "plant_refused", None)
    return ask(plant) if ask is not None else None
