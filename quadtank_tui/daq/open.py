"""Building the Modbus backend a DAQ configuration asks for (`--daq CONFIG`).

Not a command: the CLI (commands/daq.py, cli.py) and the session process
(session/launch.py, session/client.py) both open a rig from a configuration,
and the session layer must not import a CLI module to do it.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from quadtank_tui.daq.config import load_daq_config

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant
    from quadtank_tui.daq.modbus import ModbusBackend


def open_daq(config: str | None, plant: Plant | None = None, *, quiet: bool = False) -> ModbusBackend | None:
    """The Modbus backend a `--daq CONFIG` asks for (None without one), wired for
    `plant` (the quadruple tank when None).  The file is read and checked now, so a
    bad one stops the program before anything runs; the link is opened on the
    first sample.  A device without a watchdog is said to have none on stderr, as
    the CLI's warnings are (unless `quiet`)."""
    if config is None:
        return None
    from quadtank_tui.daq.ist.config import is_ist

    if is_ist(config):  # the sessions' records and locks are a Modbus rig's (host, port, unit)
        raise ValueError(f"{config}: an IST rig (protocol: ist) is driven by `quadtank run --daq {config}` "
                         "in this version; the TUI and sessions drive Modbus rigs only")
    from quadtank_tui.daq.modbus import ModbusBackend  # pymodbus only when asked for

    daq_config = load_daq_config(config, plant)
    if daq_config.watchdog is None and not quiet:
        print(f"quadtank: warning: {daq_config.watchdog_line()}", file=sys.stderr)
    return ModbusBackend(daq_config)
