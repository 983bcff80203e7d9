"""The loop's controllers, C: the PID/General matrix on y1, y2 and, while it is the
type in force, the state feedback on every level of the plant (core.controllers.statefb) or the
MPC (core.controllers.mpc, through engine/mpc_control.py).

Kept apart from engine/loop.py along the seam the loop has: the sample uses
the controllers (`matrix`, `statefb`: loop.py's `_sample` calls them directly, the
hot path), this module makes and changes them.  A change of parameters is two
steps so the loop changes all or nothing: :meth:`Controllers.check` and
:meth:`Controllers.prepare` refuse (a General pole at 2/h, a state feedback there
is no design for) or design before anything moves; :meth:`Controllers.install`
then cannot refuse.  While the state feedback or the MPC runs the matrix tracks u,
so switching back to its family is bumpless, and a new state feedback or MPC starts
from the pumps in force (3.1.10) and, for the MPC, the measured levels.
"""

from __future__ import annotations

import importlib
import threading
from typing import TYPE_CHECKING, Union

from quadtank_tui.core.controllers.general import realization
from quadtank_tui.core.controllers.matrix import ELEMENTS, ControllerMatrix, Family
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.engine.backend import Levels4, Pair

if TYPE_CHECKING:  # the design needs scipy: imported when state feedback is chosen
    from quadtank_tui.core.controllers.statefb.placement import Design
    from quadtank_tui.core.controllers.statefb.plants import PlantStateFeedback
    from quadtank_tui.core.controllers.statefb.quadtank import QuadTankStateFeedback
    from quadtank_tui.engine.mpc_control import LoopMPC

    AnyStateFeedback = Union[QuadTankStateFeedback, PlantStateFeedback]
    #: What `prepare` hands `install`: a new state feedback, a new design for the
    #: running one, a new MPC, or None (nothing to do).
    StateFbChange = Union[AnyStateFeedback, Design, LoopMPC, None]
    #: The controller that owns the 2x2 as a whole (what `_sample` calls instead of the matrix).
    Whole = Union[AnyStateFeedback, LoopMPC]


#: What a state feedback's or an MPC's first design imports (scipy's linalg and
#: signal, OSQP): a second or more on a loaded machine.  Imported on the loop's
#: thread at the first switch, that stalled a rig's samples past its watchdog (the
#: guard set the pumps to 0); so a loop on a rig imports them on a thread of their
#: own as it starts (preload_designs).
DESIGN_MODULES = ("quadtank_tui.core.controllers.statefb.in_use", "quadtank_tui.core.controllers.statefb.quadtank",
                  "quadtank_tui.core.controllers.statefb.plants", "quadtank_tui.engine.mpc_control", "osqp")


def preload_designs() -> threading.Thread:
    """Import DESIGN_MODULES on a daemon thread (started, returned): a switch to
    state feedback or MPC later finds them loaded.  An import that fails here fails
    again, and is reported, where the design is asked for."""
    def load() -> None:
        for name in DESIGN_MODULES:
            try:
                importlib.import_module(name)
            except Exception:  # noqa: BLE001 - said when a design needs it
                pass

    thread = threading.Thread(target=load, name="design-preload", daemon=True)
    thread.start()
    return thread


def new_statefb(p: Parameters) -> AnyStateFeedback:
    """The state feedback `p` asks for, on its plant (ParameterError: no such design)."""
    if p.process is None:
        from quadtank_tui.core.controllers.statefb.quadtank import QuadTankStateFeedback

        return QuadTankStateFeedback(p.quadtank_constants(), p.statefb, p.tsamp)
    from quadtank_tui.core.controllers.statefb.plants import PlantStateFeedback

    return PlantStateFeedback(p.process_plant(), p.process_levels(), p.statefb, p.tsamp)


def _statefb_design(p: Parameters) -> Design:
    """A new design for the state feedback running on `p`'s plant."""
    from quadtank_tui.core.controllers.statefb.in_use import design_in_use

    return design_in_use(p)


def new_mpc(p: Parameters, old: LoopMPC | None = None) -> LoopMPC:
    """The MPC `p` asks for, on its plant (ParameterError: no such design); a redesign
    keeps `old`'s counts."""
    from quadtank_tui.engine.mpc_control import LoopMPC

    return LoopMPC(p, old.mpc.stats if old is not None else None)


def mpc_inputs(p: Parameters) -> tuple[object, ...]:
    """What the MPC's design depends on: a change of any of these makes it anew."""
    return (p.mpc, p.simulation, p.process, p.tsamp)


def _matrix_for(p: Parameters) -> ControllerMatrix:
    family = Family.PID if p.control.family.whole else p.control.family
    return ControllerMatrix(
        p.tsamp, family, p.control.structure,
        pid={e: c.pid for e, c in zip(ELEMENTS, p.controllers)},
        general={e: c.general for e, c in zip(ELEMENTS, p.controllers)},
    )


def _plant_shape(p: Parameters) -> str:
    """The plant kind: a state feedback is made anew, not redesigned, when it changes."""
    return "quadtank" if p.process is None else p.process.kind


class Controllers:
    """The controllers of `params` (ParameterError if it asks for a state feedback
    or an MPC there is no design for: the loop then falls back to the PID family)."""

    def __init__(self, params: Parameters) -> None:
        self.matrix = _matrix_for(params)
        self.statefb: AnyStateFeedback | None = None
        self.mpc: LoopMPC | None = None
        if params.control.family is Family.STATE_FEEDBACK:
            self.statefb = new_statefb(params)
        elif params.control.family is Family.MPC:
            self.mpc = new_mpc(params)
        self._offered: tuple[tuple[object, ...], LoopMPC] | None = None

    def offer(self, inputs: tuple[object, ...], mpc: LoopMPC) -> None:
        """An MPC designed off the loop's thread (engine/design_ahead.py) for
        parameters whose design inputs are `inputs`: the next prepare for them takes
        it instead of designing."""
        self._offered = (inputs, mpc)

    @property
    def whole(self) -> Whole | None:
        """The state feedback or the MPC while it is the type in force, else None."""
        return self.statefb if self.statefb is not None else self.mpc

    def check(self, new: Parameters) -> None:
        """Refuse (ParameterError) what no controller of `new` can be: a General
        element with a pole at 2/h (Tustin's z = -1)."""
        for e in new.controllers:
            realization(e.general.numerator, e.general.denominator, new.tsamp)

    def prepare(self, new: Parameters, old: Parameters) -> StateFbChange:
        """What the state feedback needs for `new`, designed (or refused) before
        anything moves: a new controller (switched to it, or another plant's), a new
        design for the one running, or None (nothing to do).  The MPC is made anew
        when its settings, the plant or the sampling time change."""
        if new.control.family is Family.MPC:
            if self.mpc is None or mpc_inputs(new) != mpc_inputs(old):
                offered, self._offered = self._offered, None
                if offered is not None and offered[0] == mpc_inputs(new):  # designed off the loop
                    if self.mpc is not None:
                        offered[1].keep_counts(self.mpc.mpc.stats)
                    return offered[1]
                return new_mpc(new, self.mpc)
            return None
        if new.control.family is not Family.STATE_FEEDBACK:
            return None
        if self.statefb is None or _plant_shape(new) != _plant_shape(old):
            return new_statefb(new)
        if (new.statefb, new.simulation, new.process, new.tsamp) == (
                old.statefb, old.simulation, old.process, old.tsamp):
            return None
        return _statefb_design(new)

    def install(self, new: Parameters, old: Parameters, change: StateFbChange, y: Levels4, u: Pair,
                automatic: bool = False) -> None:
        """Make `new`'s controllers those in force, between samples and bumpless
        (`y`, `u`: the levels and pump inputs of the moment; `automatic`: in Automatic,
        where the levels may be on their way to the references); never refuses."""
        m = self.matrix
        if new.tsamp != old.tsamp:
            m.set_sampling_time(new.tsamp)
        if not new.control.family.whole and (
                (new.control.family, new.control.structure) != (m.family, m.structure)):
            m.set_type(new.control.family, new.control.structure)
        self._install_mpc(new, change, y, u, automatic)
        self._install_statefb(new, change, y, u)
        for ij, (was, now) in zip(ELEMENTS, zip(old.controllers, new.controllers)):
            if was.pid != now.pid:
                m.set_element_params(*ij, now.pid)
            if was.general != now.general:
                m.set_element_params(*ij, now.general)

    def _install_mpc(self, new: Parameters, change: StateFbChange, y: Levels4, u: Pair, automatic: bool) -> None:
        """Switch to or redesign the MPC (it starts from the levels and the pumps of the
        moment: bumpless), or drop it."""
        if new.control.family is not Family.MPC:
            self.mpc = None
            return
        from quadtank_tui.engine.mpc_control import LoopMPC

        if isinstance(change, LoopMPC):
            self.mpc = change
            self.mpc.track(y, u, automatic)  # start at the measured levels and the pumps in force

    def _install_statefb(self, new: Parameters, change: StateFbChange, y: Levels4, u: Pair) -> None:
        """Switch to, redesign (between samples, bumpless) or drop the state feedback."""
        if new.control.family is not Family.STATE_FEEDBACK:
            self.statefb = None
            return
        from quadtank_tui.core.controllers.statefb.placement import Design
        from quadtank_tui.core.controllers.statefb.plants import PlantStateFeedback
        from quadtank_tui.core.controllers.statefb.quadtank import QuadTankStateFeedback

        if isinstance(change, (QuadTankStateFeedback, PlantStateFeedback)):
            self.statefb = change
            self.statefb.track(y, u)  # start where the pumps are (3.1.10)
        elif not isinstance(change, Design):
            return
        elif isinstance(self.statefb, PlantStateFeedback):
            self.statefb.configure(new.process_plant(), new.process_levels(), new.statefb, change)
        elif self.statefb is not None:
            self.statefb.configure(new.quadtank_constants(), new.statefb, change)

    def reset(self, element: tuple[int, int] | None = None) -> None:
        """Every controller's state cleared, or one element's of the matrix."""
        if element is not None:
            self.matrix.reset_element(*element)
            return
        self.matrix.reset()
        if (whole := self.whole) is not None:
            whole.reset()
