"""What a session is, as `quadtank sessions` lists it and its record on disk says.

Kept apart from the protocol (which imports numpy and the engine's messages) so the
launcher can look for a running session, and start one, before loading any of that:
the session process boots while the launcher loads the UI (benchmarks/tui_cost.py).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SessionInfo:
    """What `quadtank sessions` shows of one session; also its JSON record on disk."""

    id: str
    owner: str
    uid: int
    pid: int
    started: str               # ISO 8601, local time, seconds
    plant: str
    operation: str = "Simul"   # Simul | Active
    state: str = "Pause"       # Run | Pause
    logging: str = "off"       # "off", "42% (420/1000)", "unsaved 1000 rows"
    clients: int = 0
    operator: str = ""         # who controls it now ("" while nobody is attached as operator)
    socket: str = ""
    cwd: str = ""
    daq: str = ""              # the DAQ configuration file ("" for the simulator only)
    headless: bool = False     # `quadtank run --detach`
    note: str = ""             # what the session did by itself (the unattended policy)
    watchdog: str = ""         # the DAQ's own watchdog: "device", or "none" (said by `quadtank sessions`)
    ended: str = ""            # why it ended ("" while it runs): its record is kept a while (runtime.ENDED_KEPT)
    ended_at: str = ""         # ISO 8601, local time, seconds
