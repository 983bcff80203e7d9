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


def replay(args: argparse.Namespace) -> int:
    """Run the replay `args` asks for and print a one-line summary."""
    from quadtank_tui.commands.identify import read_sampled
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


def _index(name: str, prefix: str) -> int:
    """0-based number of a y<n> / u<n> column name; a large number for any other."""
    if name.startswith(prefix) and name[1:].isdigit() and int(name[1:]) >= 1:
        return int(name[1:]) - 1
    return 1 << 30
