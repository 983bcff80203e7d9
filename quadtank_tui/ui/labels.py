"""Labels the windows and the widgets both show: controller element and type
names, a generator's channel and the logger's state.

Kept here, below both, so that a widget never imports a window (widgets are the
lower of the two: windows are built from widgets).
"""

from __future__ import annotations

from quadtank_tui.core.parameters import Family, Parameters, Structure
from quadtank_tui.engine.snapshot import LogStatus

#: Element index 0..3 -> its name in the matrix (row = input i, column = error j).
ELEMENT_NAMES = ("11", "12", "21", "22")

#: The four structures, the state feedback and the MPC (types on the 2x2 as a whole,
#: whatever the structure), in the order the Type window lists them.
TYPES: tuple[tuple[Family, Structure, str], ...] = (
    (Family.PID, Structure.DECENTRALIZED, "PID decentralized"),
    (Family.PID, Structure.FULL_MATRIX, "PID full matrix"),
    (Family.GENERAL, Structure.DECENTRALIZED, "General decentral."),
    (Family.GENERAL, Structure.FULL_MATRIX, "General full matrix"),
    (Family.STATE_FEEDBACK, Structure.DECENTRALIZED, "State feedback"),
    (Family.MPC, Structure.DECENTRALIZED, "MPC"),
)


def type_index(p: Parameters) -> int:
    """The row of TYPES the parameters' family and structure are."""
    c = p.control
    return next(n for n, (f, s, _) in enumerate(TYPES)
                if f is c.family and (s is c.structure or f.whole))


def type_modified(p: Parameters, defaults: Parameters) -> bool:
    """Whether the controller type differs from the default (shown dim italic)."""
    return p.is_modified("CONTROL.Type", defaults) or p.is_modified("CONTROL.Structure", defaults)


def channel_label(channel: int, control: str) -> str:
    """u1/u2 in Manual, ref1/ref2 in Automatic: what the generator drives (M3-M4)."""
    return f"u{channel}" if control == "Manual" else f"ref{channel}"


def log_state(log: LogStatus) -> str:
    """One line on what the logger is doing (the window and the status line)."""
    if log.active:
        return f"logging {log.rows}/{log.points}"
    if log.unsaved:
        return f"{log.rows} rows not saved"
    if log.saved_path:
        return f"saved {log.saved_path}"
    return "off"


#: What a refused command's notification is titled: what the user asked for, in
#: the words of the screen (never the engine's class name: "SetState").
_COMMAND_TITLES = {
    "SetParams": "Settings", "SetDefaults": "Defaults", "NudgeMean": "Input mean", "AddWater": "Add water",
    "SetFault": "Fault", "SetDisturbance": "Disturbance pump", "ResetControllers": "Controller reset",
    "LogOn": "LogOn", "LogOff": "LogOff", "LogSave": "Save log", "LogDiscard": "Discard log",
    "LoadPar": "Load parameters", "SavePar": "Save parameters", "SetSpeed": "Speed",
    "StartCalibration": "Calibration", "CalibrationHeights": "Calibration", "CancelCalibration": "Calibration",
    "InstallPar": "Parameters",
}


def command_title(command: object) -> str:
    """The title of a notification about `command`: Run, Pause, Reset, Simul,
    Active, Manual or Automatic for the mode changes, else its words."""
    for field in ("state", "operation", "mode"):
        value = getattr(command, field, None)
        if isinstance(value, str):
            return value
    name = type(command).__name__
    return _COMMAND_TITLES.get(name, name)
