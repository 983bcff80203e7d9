"""Commands: the only way anything changes the running loop.

The UI, the CLI's scripted experiments and the tests build these immutable values
and hand them to the engine's one thread-safe entry point; the loop applies them
between samples.  A refused command changes nothing and comes back with a message
that says why (the UI shows it next to the field or as a notification).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, Mapping, Union

if TYPE_CHECKING:
    from quadtank_tui.core.parameters import Parameters

Operation = Literal["Simul", "Active"]
State = Literal["Run", "Pause", "Reset"]
ControlModeName = Literal["Manual", "Automatic"]


@dataclass(frozen=True)
class SetParams:
    """Set parameters by their `.par` names ("CONTROLLER ONE.K": 3.0, ...), all or none.

    This is how every parameter window's Set acts; a single value is a one-item map.
    """

    values: Mapping[str, Any]


@dataclass(frozen=True)
class SetDefaults:
    """A window's Default action: restore these keys to the defaults (`default.par`)."""

    keys: tuple[str, ...]


@dataclass(frozen=True)
class SetOperation:
    """Simul / Active (Active only when a DAQ backend is configured)."""

    operation: Operation


@dataclass(frozen=True)
class SetState:
    """Run / Pause / Reset (Reset clears every state, returns the simulation to its
    operating point, then pauses)."""

    state: State


@dataclass(frozen=True)
class SetControlMode:
    """Manual / Automatic; bumpless: the generator means are adjusted on the switch."""

    mode: ControlModeName


@dataclass(frozen=True)
class NudgeMean:
    """Move channel 1 or 2's mean progressively by `delta` (normalized)."""

    channel: int
    delta: float


@dataclass(frozen=True)
class AddWater:
    """Simul only: pour `amount` (normalized level, may be negative) into tank 1..4."""

    tank: int
    amount: float


@dataclass(frozen=True)
class SetFault:
    """Simul only: switch a fault on (`on`) or off (core.faults: kind, 1-based
    target tank/pump/sensor/valve, value)."""

    kind: str
    target: int
    value: float = 0.0
    on: bool = True


@dataclass(frozen=True)
class SetDisturbance:
    """The two disturbance pumps at fractions d1, d2 of full PWM, 0..1 (None: as it
    is): an IST rig's in Active (daq/ist/: the last two bytes of its pump frames),
    the simulated quadruple tank's inflow into tanks 1 and 2 in Simul
    (core.disturbance).  Every safe state (Pause on a rig, a fault, Reset, the end)
    puts them at 0."""

    d1: float | None = None
    d2: float | None = None


@dataclass(frozen=True)
class ResetControllers:
    """Reset all controller states, or one element (i, j) with i, j in 1..2."""

    element: tuple[int, int] | None = None


@dataclass(frozen=True)
class LogOn:
    """Start logging with the LOGGING parameters in force.  `points`: rows to take
    instead of LOGGING.Points (a headless run without a script logs every sample
    of its duration, beyond the Logging window's limit)."""

    points: int | None = None


@dataclass(frozen=True)
class LogOff:
    """Stop logging; the rows so far are kept (in the partial file) until Save."""


@dataclass(frozen=True)
class LogSave:
    """Save the log as `logs/<name>.log`; refused if it exists unless `overwrite`."""

    name: str | None = None
    overwrite: bool = False


@dataclass(frozen=True)
class LogDiscard:
    """Throw the unsaved log away (asked for by Exit after a confirmation)."""


@dataclass(frozen=True)
class LoadPar:
    """Load all parameters from `params/<name>.par` (`default`, `preset` reserved)."""

    name: str


@dataclass(frozen=True)
class SavePar:
    """Save all parameters as `params/<name>.par`; refused for reserved names, and if
    the file exists unless `overwrite`."""

    name: str
    overwrite: bool = False
    #: write `default.par` (the name is then ignored): an administrator's save, the
    #: sender checked the role (session.roles.require_administrator)
    defaults: bool = False


@dataclass(frozen=True)
class SetSpeed:
    """Simul with a virtual clock: process seconds per wall second, 1..1000."""

    factor: float


@dataclass(frozen=True)
class StartCalibration:
    """Active only: the steady-state calibration on the rig (Desautel 2.3).  The
    control loop pauses; both pumps are held at each of `volts` (V) until every
    sensor stays within `tol` V for `window` seconds (one read a sample; at most
    `timeout` s), then the engine waits for the heights read on the scales
    (CalibrationHeights)."""

    volts: tuple[float, ...]
    window: float = 60.0
    tol: float = 0.004
    timeout: float = 3600.0


@dataclass(frozen=True)
class CalibrationHeights:
    """The heights (cm) read on the tanks' scales for the settled state shown."""

    levels: tuple[float, ...]


@dataclass(frozen=True)
class CancelCalibration:
    """Stop the calibration, pumps at 0; when it has ended, forget its status."""


Command = Union[
    SetParams, SetDefaults, SetOperation, SetState, SetControlMode, NudgeMean, AddWater,
    SetFault, SetDisturbance, ResetControllers, LogOn, LogOff, LogSave, LogDiscard, LoadPar, SavePar, SetSpeed,
    StartCalibration, CalibrationHeights, CancelCalibration,
]


@dataclass(frozen=True)
class InstallPar:
    """A LoadPar whose file was read and checked off the loop's thread
    (engine/parload.py): the loop only installs `params`.  Internal to the engine
    and the session: not a Command, never accepted from a client."""

    name: str
    params: Parameters
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class CommandResult:
    """What became of a command: `ok`, and a message for the user (why it was
    refused, or a warning such as unknown keys in a loaded file)."""

    ok: bool
    message: str = ""
    warnings: tuple[str, ...] = field(default=())

    @classmethod
    def refused(cls, message: str) -> CommandResult:
        return cls(False, message)
