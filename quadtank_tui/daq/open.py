"""Reading the rig a DAQ configuration describes (`--daq CONFIG`) and building its
backend (open_daq): a Modbus map, or an IST serial rig when the file says
`protocol: ist`; the same for `quadtank run`, the TUI and a session.

Not a command: the CLI (commands/daq.py, commands/lab.py, cli.py) and the session
process (session/launch.py, session/client.py) both open a rig from a
configuration, and the session layer must not import a CLI module to do it.  The
file is read once, here, and its text decides the protocol (load_rig_config):
the callers ask the configuration it returns, never the file again.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable

from quadtank_tui.daq.config import PRESETS, DaqConfig, load_daq_config, parse_daq_config
from quadtank_tui.daq.ist.config import IstConfig, parse_ist_config, says_ist
from quadtank_tui.daq.config_checks import config_error
from quadtank_tui.files.yamltext import read_text

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant
    from quadtank_tui.daq.ist.backend import IstBackend
    from quadtank_tui.daq.modbus import ModbusBackend

#: Where a caller wants the warnings of a configuration read (commands.warn: one
#: `quadtank: warning:` line each on stderr); this layer does not print them itself.
Warn = Callable[[Iterable[str]], None]


def load_rig_config(path: Path | str, plant: Plant | None = None) -> DaqConfig | IstConfig:
    """The configuration of the rig a DAQ file (or a preset name) describes, read
    and checked once: an IST serial rig's when it says `protocol: ist`, else the
    Modbus map for the channels of `plant` (the quadruple tank when None)."""
    if str(path) in PRESETS:
        return load_daq_config(path, plant)
    text = read_text(path, config_error)  # the hostile-file checks: no FIFO, no huge file
    if says_ist(text):
        return parse_ist_config(text, name=str(path))
    return parse_daq_config(text, name=str(path), plant=plant)


def open_daq(config: str | None, plant: Plant | None = None, *,
             warn: Warn | None = None) -> ModbusBackend | IstBackend | None:
    """The backend of the rig a `--daq CONFIG` describes (None without one), wired
    for `plant` (the quadruple tank when None): a Modbus map or an IST serial rig,
    for `quadtank run`, the TUI and a session alike.  The file is read and checked
    now, so a bad one stops the program before anything runs; the link is opened on
    the first sample.  A Modbus device without a watchdog is said to have none: the
    line goes to `warn` (the commands print it as their other warnings; None: not
    said)."""
    if config is None:
        return None
    rig = load_rig_config(config, plant)
    if isinstance(rig, DaqConfig):
        return _modbus(rig, warn)
    from quadtank_tui.daq.ist.backend import IstBackend

    backend = IstBackend(rig)
    if plant is not None and (why := backend.plant_refused(plant)):
        raise ValueError(why)
    return backend


def _modbus(config: DaqConfig, warn: Warn | None) -> ModbusBackend:
    from quadtank_tui.daq.modbus import ModbusBackend  # pymodbus only when asked for

    if config.watchdog is None and warn is not None:
        warn([config.watchdog_line()])
    return ModbusBackend(config)
