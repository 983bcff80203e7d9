"""A new MPC designed off the loop's thread.

The first switch to MPC imports scipy and OSQP and designs (two Riccati
equations, the QP's setup): about 2 s on a loaded machine, 56-111 ms with the
modules loaded.  On the loop's thread those are samples the plant does not get (a
rig's watchdog fires at 1 s).  So a driver that samples (a session) hands a
SetParams that needs a new MPC design to a thread of its own (`MPCDesigning.start`)
and keeps sampling; the commands after it wait behind it, in order (as behind a
LoadPar, engine/parload.py), and once the design is done the loop installs it
between two samples (Controllers.offer, then the SetParams as usual).  A design
that fails is done again by the SetParams on the loop's thread, which refuses it
with the key and the reason, as it always has.
"""

from __future__ import annotations

import threading
from concurrent.futures import Future
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from quadtank_tui.core.controllers.matrix import Family
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.engine import controllers
from quadtank_tui.engine.controllers import mpc_inputs

if TYPE_CHECKING:
    from quadtank_tui.engine.loop import ControlLoop
    from quadtank_tui.engine.mpc_control import LoopMPC


def needs_mpc_design(loop: ControlLoop, cmd: SetParams) -> Parameters | None:
    """The parameters `cmd` makes when they need an MPC the loop does not have (a
    switch to MPC, or new settings for it), else None (also when the values are
    not plain settings or are refused: the loop says so on its own thread)."""
    if any("." not in k or k.startswith("PLANT.") or k == "CONTROL.Mode" for k in cmd.values):
        return None
    try:
        new = loop.params.with_values(cmd.values)
    except Exception:  # noqa: BLE001 - refused where it is applied
        return None
    if new.control.family is not Family.MPC:
        return None
    running = loop.controllers.mpc
    if running is not None and mpc_inputs(new) == mpc_inputs(loop.params):
        return None
    return new


@dataclass(frozen=True)
class MPCDesigning:
    """A SetParams waiting for its MPC, designed on a thread of its own; `future`
    holds (what it was designed for, the design), or None if it failed."""

    command: SetParams
    future: Future[tuple[tuple[object, ...], LoopMPC] | None]

    @classmethod
    def start(cls, cmd: SetParams, new: Parameters, wake: Callable[[], None]) -> MPCDesigning:
        """Start designing for `new`; `wake()` is called (from the designer's thread)
        once it is done."""
        fut: Future[tuple[tuple[object, ...], LoopMPC] | None] = Future()

        def design() -> None:
            try:
                fut.set_result((mpc_inputs(new), controllers.new_mpc(new)))
            except BaseException:  # noqa: BLE001 - the SetParams designs again and says why
                fut.set_result(None)
            wake()

        threading.Thread(target=design, name="quadtank-mpc-design", daemon=True).start()
        return cls(cmd, fut)

    @property
    def done(self) -> bool:
        return self.future.done()
