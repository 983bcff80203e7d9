"""`quadtank run --inputs-from LOG`: the simulator of a `.par` driven open loop by
a log's pump signals, written as a log whose rows line up with it.

A rig's run and its twin then compare row by row (`quadtank log compare`, or
`quadtank identify --validate-on`).  Row k of the new log holds the sensors the
simulator reads at sample k and the pump signals of row k of the source log, held
for one sampling time (the loop's order: read, act, log).  The levels at the first
row, measured and unmeasured tanks, are those that best explain the log's first 20
readings with the `.par`'s constants held (core.identify.physical.estimate_initial,
as `identify --validate-on` does): a rig's log rarely starts exactly at rest.  The simulator is the plant's own step
(core.identify.physical.simulate), so a log the simulator wrote with the same
`.par` comes back to the log's last digit.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from quadtank_tui.commands import UsageError, warn

#: The largest log a replay reads, bytes (about 215,000 rows of 9 columns: 3 h of
#: 50 ms samples, 60 h of 1 s): the simulator integrates every row, 0.1-1.4 ms
#: each, so a 200 MB log (4.2 million rows) ran for hours.
MAX_REPLAY_BYTES = 20_000_000


def replay(args: argparse.Namespace) -> int:
    """Run the replay `args` asks for and print a one-line summary."""
    _refuse_large(args.inputs_from)  # before the simulator's imports: a refusal comes at once
    from quadtank_tui.commands import read_sampled
    from quadtank_tui.core.identify.physical import estimate_initial, experiment_from_columns, simulate
    from quadtank_tui.core.plants.common import FULL_SCALE_V
    from quadtank_tui.engine.headless import refuse_log_target
    from quadtank_tui.engine.runner import load_parameters, virtual_epoch
    from quadtank_tui.files.atomic import atomic_write_text
    from quadtank_tui.files.log_writer import format_header, format_row
    from quadtank_tui.files.par import ParStore

    for option, given in (("--script", args.script), ("--daq", args.daq or getattr(args, "daq_global", None)),
                          ("--detach", args.detach), ("--realtime", args.realtime), ("--speed", args.speed)):
        if given:
            raise UsageError(f"--inputs-from replays a log on the simulator, open loop: {option} does not apply")
    source = args.inputs_from
    out = Path(args.log)
    try:
        refuse_log_target(out)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if out.resolve() == Path(source).resolve():
        raise UsageError(f"--log {out}: that is the log being replayed; name another file")
    params, warnings = load_parameters(args.par, ParStore(Path("params")))
    warn(warnings)
    plant = params.process_plant()
    log, tsamp = read_sampled(source)
    columns = log.columns()
    exp = experiment_from_columns(source, tsamp, columns, plant)
    x = simulate(plant, estimate_initial(plant, exp, []), exp.u, tsamp)
    sensors = np.array([plant.output(row) for row in x]) / FULL_SCALE_V
    keep = [v for v in log.variables if _index(v, "y") < len(plant.outputs) or _index(v, "u") < len(plant.inputs)]
    dropped = [v for v in log.variables if v not in keep]
    if dropped:
        warn([f"{source}: {' '.join(dropped)} not replayed (not a sensor or pump of the {plant.kind})"])
    data = np.column_stack([sensors[:, _index(v, "y")] if v.startswith("y") else columns[v] for v in keep])
    created = log.created or virtual_epoch()
    atomic_write_text(out, format_header(keep, tsamp, created) + "".join(format_row(r) for r in data))
    if duration := args.duration:
        if abs(duration - log.rows * tsamp) > tsamp:
            warn([f"--duration {duration:g} ignored: the replay lasts as long as {source} ({log.rows * tsamp:g} s)"])
    print(f"replayed  {source} ({log.rows} rows, TSamp {tsamp:g} s) on the {plant.title}, open loop\n"
          f"log       {out} ({log.rows} rows)")
    return 0


def _refuse_large(source: str) -> None:
    """UsageError for a log larger than MAX_REPLAY_BYTES, from its size alone (what
    is not a regular file is left to the reader, which refuses it)."""
    import os
    import stat

    from quadtank_tui.files.log_reader import ROW_BYTES

    try:
        st = os.stat(source)
    except OSError:
        return
    if stat.S_ISREG(st.st_mode) and st.st_size > MAX_REPLAY_BYTES:
        raise UsageError(f"{source}: {st.st_size / 1e6:,.1f} MB, larger than a replay reads "
                         f"({MAX_REPLAY_BYTES / 1e6:g} MB, about {MAX_REPLAY_BYTES // ROW_BYTES:,} rows of 9 "
                         "columns): replay a part of it")


def _index(name: str, prefix: str) -> int:
    """0-based number of a y<n> / u<n> column name; a large number for any other."""
    if name.startswith(prefix) and name[1:].isdigit() and int(name[1:]) >= 1:
        return int(name[1:]) - 1
    return 1 << 30
