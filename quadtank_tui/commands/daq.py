"""`quadtank rig`, `quadtank daq` and `--daq`: parsers and commands kept out of
cli.py's way.

cli.py adds the subcommands with `add_rig_parser` / `add_daq_parser` and the
option with `add_daq_option`.  Building a backend from a DAQ configuration is
not a command: it is daq/open.py's `open_daq`, for `run`, the TUI and a session
alike (the session process uses it too).  `python -m quadtank_tui.commands.daq rig ...` runs the rig alone.
"""

from __future__ import annotations

import argparse
import ipaddress
import math
import sys
from typing import TYPE_CHECKING, Literal

from quadtank_tui.commands import warn
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.daq.config import PRESETS, DaqConfig, load_daq_config
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.daq.open import load_rig_config, open_daq
from quadtank_tui.engine.backend import BackendError

# The commands import what they run inside their handlers (the rig: asyncio; the
# preset parameters: numpy), so building the parser, which every `quadtank`
# command does, stays cheap.
if TYPE_CHECKING:  # pymodbus is imported only when a DAQ is used
    from quadtank_tui.core.plants import Plant
    from quadtank_tui.daq.calibrate import Result
    from quadtank_tui.daq.ist.backend import IstBackend
    from quadtank_tui.daq.modbus import ModbusBackend


def add_rig_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "rig",
        help="serve the simulated process over Modbus TCP (a virtual rig for Active mode)",
        description="A Modbus TCP server whose input registers are the simulated level-sensor "
        "voltages and whose output registers drive the simulated pumps, in real time times "
        "--speed.  Point `quadtank --daq params/virtual-rig.yaml` at it.",
    )
    p.add_argument("--par", metavar="FILE", help="a .par file: its PLANT (else SIMULATION) section "
                   "gives the plant and the starting levels (default: the built-in preset, P-)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1, loopback only)")
    p.add_argument("--port", type=int, default=5020, help="TCP port (default 5020; 0 picks a free one)")
    p.add_argument("--map", default="labjack", metavar="NAME|FILE",
                   help=f"register map and wiring: a preset ({', '.join(PRESETS)}) or a DAQ "
                   "configuration file (default labjack), read for the plant of --par: a "
                   "two-tank plant serves two level inputs")
    p.add_argument("--speed", type=float, default=1.0, help="process seconds per wall second (default 1)")
    p.add_argument("--noise", type=float, default=0.0, metavar="SIGMA",
                   help="sensor noise, standard deviation in volts (default 0)")
    p.add_argument("--offset", type=float, default=0.0, metavar="V", help="sensor zero offset, volts")
    p.add_argument("--lsb", type=float, default=0.0, metavar="V",
                   help="sensor quantization step, volts (default 0: none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    p.add_argument("--watchdog", type=float, default=0.0, metavar="S",
                   help="start with the map's watchdog armed for S wall seconds, the pumps to 0 on a "
                   "timeout, as a program left it (default 0: off, as a LabJack out of the box, until "
                   "a program arms it through its registers)")
    p.add_argument("--reply-delay", type=float, default=0.0, metavar="S",
                   help="answer every request S seconds late (to try a slow link)")
    p.add_argument("--status", type=float, default=0.0, metavar="S",
                   help="print the levels and pumps every S seconds (default 0: never)")
    p.add_argument("--protocol", choices=("modbus", "ist"), default="modbus",
                   help="modbus (default): a Modbus TCP server; ist: the IST Lisbon rig's Arduino on a new "
                   "pseudo-terminal (its path is printed; --map may give params/daq-ist.yaml's constants)")
    p.add_argument("--reset", type=float, default=1.0, metavar="S",
                   help="with --protocol ist: the seconds the device is deaf after the port opens (default 1)")
    p.add_argument("--fault", action="append", default=[], metavar="KIND:N[:VALUE]",
                   help="inject a fault from the start, e.g. leak:1:0.02, clog:2:0.7, weak_pump:1:0.5, "
                   "sensor_bias:1:0.05 (normalized), sensor_stuck:2; repeatable")
    p.set_defaults(handler=cmd_rig)


def parse_fault(text: str) -> tuple[str, int, float]:
    """KIND:N[:VALUE] of --fault; ValueError naming the option."""
    parts = text.split(":")
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        return parts[0], int(parts[1]), float(parts[2]) if len(parts) == 3 else 0.0
    except ValueError:
        raise ValueError(f"--fault {text!r}: expected KIND:N or KIND:N:VALUE, e.g. leak:1:0.02") from None


def cmd_rig(args: argparse.Namespace) -> int:
    import asyncio

    from quadtank_tui.core.parameters import PRESET
    from quadtank_tui.daq.rig import SensorModel, VirtualRig, serve_rig
    from quadtank_tui.files.par import read_par  # files layer, only when a .par is given

    if args.protocol == "ist":
        from quadtank_tui.commands.daq_ist import cmd_rig_ist

        return cmd_rig_ist(args)
    if args.par is not None:
        read = read_par(args.par)
        warn(read.warnings)
        params = read.params
    else:
        params = PRESET
    plant = params.quadtank_constants() if params.process is None else params.process_plant()
    config = load_daq_config(args.map, params.process_plant())
    if not (args.speed > 0 and math.isfinite(args.speed)):
        raise ValueError(f"--speed must be a number > 0, got {args.speed}")
    if not math.isfinite(args.offset):
        raise ValueError(f"--offset must be a number of volts, got {args.offset}")
    for name in ("noise", "lsb", "watchdog", "reply_delay", "status"):
        value = getattr(args, name)
        if not (value >= 0 and math.isfinite(value)):  # NaN fails both
            raise ValueError(f"--{name.replace('_', '-')} must be a number >= 0, got {value}")
    if not 0 <= args.port <= 65535:
        raise ValueError(f"--port must be in 0..65535, got {args.port}")
    if not _is_loopback(args.host):
        print(f"quadtank rig: warning: binding {args.host}: the rig is reachable from the network",
              file=sys.stderr)
    faults = [parse_fault(text) for text in args.fault]
    rig = VirtualRig(
        config, plant, params.process_levels(),
        speed=args.speed, watchdog=args.watchdog,
        sensors=SensorModel(noise=args.noise, offset=args.offset, lsb=args.lsb, seed=args.seed),
        report=lambda text: print(f"quadtank rig: {text}", flush=True),
    )
    from quadtank_tui.core.faults import Fault

    for kind, target, value in faults:
        began = rig.set_fault(Fault(kind, target, value))
        print(f"quadtank rig: fault on: {began.label()}", flush=True)
    asyncio.run(serve_rig(rig, args.host, args.port, reply_delay=args.reply_delay, status_every=args.status))
    return 0


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


# --- quadtank daq check | fit: bringing up a real rig ------------------------------------

def add_daq_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("daq", help="check a DAQ link, fit a sensor calibration",
                       description="Bring up a rig: read its sensors once through a DAQ "
                       "configuration (nothing is written), or fit a level sensor's gain and "
                       "offset from steady-state pairs (Desautel 2.3).")
    daqsub = p.add_subparsers(dest="daq_command", metavar="ACTION", required=True)
    check = daqsub.add_parser("check", help="read the level sensors once; writes nothing")
    check.add_argument("config", metavar="CONFIG", help="a DAQ configuration file or preset name")
    check.add_argument("--par", metavar="FILE", help="a .par file: the plant whose channels are read "
                       "(its PLANT section; default the quadruple tank, four levels)")
    check.set_defaults(handler=cmd_daq_check)
    fit = daqsub.add_parser("fit", help="least-squares gain and offset from VOLTS:CM pairs")
    fit.add_argument("pairs", metavar="VOLTS:CM", nargs="+",
                     help="a steady-state sensor voltage and the level read off the scale, e.g. 1.34:7.5")
    fit.add_argument("--tank", type=int, choices=(1, 2, 3, 4), default=1,
                     help="the tank, for the configuration line printed (default 1)")
    fit.set_defaults(handler=cmd_daq_fit)
    cal = daqsub.add_parser(
        "calibrate", help="the steady-state calibration on the rig, or from a file of pairs",
        description="Hold the pumps at each voltage until the four sensors settle, ask for the "
        "heights read on the tanks' scales, and fit each sensor's gain and offset by least "
        "squares (Desautel 2.3); with --par also the outlet areas. Or fit pairs from a file "
        "(--pairs). Prints the configuration lines and the pairs; --write puts them into a "
        "DAQ configuration file.")
    cal.add_argument("config", metavar="CONFIG", nargs="?",
                     help="the DAQ configuration of the rig (not needed with --pairs)")
    cal.add_argument("--volts", metavar="V", type=float, nargs="+", default=[2.0, 2.5, 3.0, 3.5],
                     help="pump voltages, both pumps alike (default 2 2.5 3 3.5)")
    cal.add_argument("--pairs", metavar="FILE", help="fit these settled states instead of running the rig")
    cal.add_argument("--par", metavar="FILE", help="a .par file: its pumps and valves give the outlet areas")
    cal.add_argument("--poll", metavar="S", type=float, default=2.0, help="seconds between reads (default 2)")
    cal.add_argument("--window", metavar="N", type=int, default=30,
                     help="reads that must agree within --tol to count as settled (default 30)")
    cal.add_argument("--tol", metavar="V", type=float, default=0.004, help="settling band, volts (default 0.004)")
    cal.add_argument("--timeout", metavar="S", type=float, default=3600.0,
                     help="give up after S seconds at one voltage (default 3600)")
    cal.add_argument("--write", metavar="CONFIG_FILE", nargs="?", const="",
                     help="write the result: the gains and offsets into this DAQ configuration file "
                     "(default: CONFIG), the outlets (a1..a4 as TimeConst1..4, or the cascade's alpha1, "
                     "alpha2) into the --par file; prints what changes and asks first (comments are kept)")
    cal.add_argument("--yes", action="store_true",
                     help="with --write: write without asking (scripts; without a terminal --write needs it)")
    cal.set_defaults(handler=cmd_daq_calibrate)


def cmd_daq_check(args: argparse.Namespace) -> int:
    """Read-only on purpose: checking a link must never move a pump."""
    from quadtank_tui.daq.modbus import ModbusBackend

    config = load_rig_config(args.config, _par_plant(args.par))
    if isinstance(config, IstConfig):
        from quadtank_tui.commands.daq_ist import cmd_check_ist

        return cmd_check_ist(config)
    backend = ModbusBackend(config)
    try:
        volts = backend.read_raw_volts()
        differ = backend.identity_mismatches()
    except BackendError as exc:
        print(f"quadtank: {exc}", file=sys.stderr)
        return 1
    finally:
        backend.close()
    if differ and differ[0]:
        print(f"quadtank: {args.config}: not the rig at {config.host}:{config.port}: {', '.join(differ[0])}; "
              "its pumps would get other volts than this file assumes "
              "(params/virtual-rig.yaml is the virtual rig's file)", file=sys.stderr)
        return 2
    if differ and differ[1]:
        warn([f"{args.config}: the rig's sensors differ from this file's calibration: {', '.join(differ[1])} "
              "(quadtank daq calibrate fits them)"])
    print(f"{backend.description}  (device id {config.device_id}, timeout {config.timeout:g} s; "
          f"{config.plant.kind}: {len(config.tanks)} level, {len(config.pump_channels)} pump channels)")
    faults = 0
    unit = config.plant.unit
    for i, tank in enumerate(config.tanks):
        ch = config.channels[tank]
        level = config.sensors[i].level(volts[i])
        y = config.sensor_gains[i] * level / FULL_SCALE_V
        lo, hi = config.plausible_range(i + 1)
        mark = "" if lo <= level <= hi else f"  SENSOR FAULT: outside its plausible {lo:g}..{hi:g} {unit}"
        faults += bool(mark)
        print(f"tank {i + 1}  {ch:>6}  {volts[i]:8.4f} V  {level:7.{2 if unit == 'cm' else 4}f} {unit}  y = {y:.4f}{mark}")
    if not faults:
        backend.interlock.update(backend.height_fractions(volts))
    for alarm in backend.alarms:
        print(alarm)
    print(config.watchdog_line())
    print("rig identity: none served (a real device): the file's calibration is not checked against it"
          if differ is None else "rig identity: the virtual rig's pump amplifiers and sensors are this file's"
          if not differ[1] else "rig identity: the virtual rig's pump amplifiers are this file's, its sensors not")
    return 1 if faults else 0


def cmd_daq_fit(args: argparse.Namespace) -> int:
    from quadtank_tui.core.calibration.fits import fit_sensor

    volts, levels = [], []
    for pair in args.pairs:
        v, sep, h = pair.partition(":")
        try:
            volts.append(float(v))
            levels.append(float(h))
        except ValueError:
            raise ValueError(f"{pair!r}: expected VOLTS:CM, e.g. 1.34:7.5") from None
        if not sep:
            raise ValueError(f"{pair!r}: expected VOLTS:CM, e.g. 1.34:7.5")
    cal = fit_sensor(volts, levels)
    print(f"gain {cal.gain:.4f} cm/V  offset {cal.offset:.4f} cm  rms residual {cal.rms:.3f} cm")
    print(f"  tank{args.tank}: {{gain: {cal.gain:.4f}, offset: {cal.offset:.4f}}}")
    return 0


def cmd_daq_calibrate(args: argparse.Namespace) -> int:
    from quadtank_tui.core.calibration.procedure import SettleRule
    from quadtank_tui.daq.calibrate import fit_pairs, format_result, read_pairs, run_procedure

    plant = None
    if args.par is not None:
        from quadtank_tui.files.par import read_par

        read = read_par(args.par)
        warn(read.warnings)
        plant = read.params.process_plant()
    rig = load_rig_config(args.config) if args.config is not None else None
    if args.pairs is not None:
        pairs = read_pairs(args.pairs)
    else:
        if rig is None:
            raise ValueError("give the rig's DAQ configuration, or --pairs FILE")
        for name in ("poll", "tol", "timeout"):
            if not getattr(args, name) > 0:
                raise ValueError(f"--{name} must be > 0, got {getattr(args, name)}")
        if args.window < 2:
            raise ValueError(f"--window must be >= 2 reads, got {args.window}")
        if any(not 0 <= v <= 10 for v in args.volts):
            raise ValueError("--volts must be within 0..10 V")
        backend = _calibration_backend(rig, args.config, args.write)
        try:
            pairs = run_procedure(
                backend, args.volts, SettleRule(args.window, args.tol, args.timeout), _ask_heights,
                poll=args.poll, report=lambda text: print(text, file=sys.stderr, flush=True))
        except BackendError as exc:
            print(f"quadtank: {exc}", file=sys.stderr)
            return 1
        finally:
            backend.close()
        print("# the settled states (save them to refit with --pairs FILE)")
        print(pairs.format(), end="")
    result = fit_pairs(pairs, plant)
    if isinstance(rig, IstConfig):
        from quadtank_tui.commands.daq_ist import format_ist_result

        print(format_ist_result(result, plant))
        return 0
    print(format_result(result, plant))
    if args.write is not None:
        return _write_calibration(result, args.write or _daq_file(args.config), args.par, yes=args.yes)
    return 0


def _calibration_backend(rig: DaqConfig | IstConfig, config: str, write: str | None) -> ModbusBackend | IstBackend:
    """The backend `daq calibrate CONFIG` holds the pumps with.  For an IST rig the
    sensors' "volts" are their ratios r (its level is linear in r), and --write is
    refused: its file's keys are dh_dr and h0."""
    if isinstance(rig, DaqConfig):
        from quadtank_tui.daq.modbus import ModbusBackend

        return ModbusBackend(rig)
    if write is not None:
        raise ValueError(f"{config}: --write does not edit an IST file yet; copy the dh_dr and h0 "
                         "lines the fit prints into its calibration: section")
    from quadtank_tui.daq.ist.backend import IstBackend

    return IstBackend(rig)


def _daq_file(config: str | None) -> str | None:
    """CONFIG when it is a file (a preset name is not one to write into)."""
    from pathlib import Path

    return config if config is not None and Path(config).is_file() else None


def _write_calibration(result: Result, daq_file: str | None, par_file: str | None, *, yes: bool) -> int:
    """Print what changes, ask (a terminal; --yes skips it), then write atomically.
    Without a terminal and without --yes nothing is written (exit 1)."""
    from quadtank_tui.daq.calibrate import commit, plan_writes

    if daq_file is None and par_file is None:
        raise ValueError("--write: give the DAQ configuration file to write (--write FILE) and/or --par FILE")
    planned = plan_writes(result, daq_file, par_file)
    if not planned:
        print("nothing to write: the files already hold this calibration", file=sys.stderr)
        return 0
    for p in planned:
        print(p.diff(), end="")
    names = " and ".join(str(p.path) for p in planned)
    if not yes:
        if not sys.stdin.isatty():
            print(f"quadtank: not written: no terminal to ask whether to change {names}; "
                  "add --yes to write without asking", file=sys.stderr)
            return 1
        print(f"write this into {names}? [y/N] ", end="", file=sys.stderr, flush=True)
        if sys.stdin.readline().strip().lower() not in ("y", "yes"):
            print(f"{names} left as they were", file=sys.stderr)
            return 0
    commit(planned)
    print(f"calibration written into {names}", file=sys.stderr)
    return 0


def _ask_heights(volts: tuple[float, float], settled: tuple[float, ...]) -> list[float]:
    """The operator types the four heights read on the scales (stdin)."""
    while True:
        print("heights on the scales, cm (h1 h2 h3 h4): ", end="", file=sys.stderr, flush=True)
        line = sys.stdin.readline()
        if not line:
            raise ValueError("no heights given (end of input)")
        try:
            heights = [float(w) for w in line.replace(",", " ").split()]
        except ValueError:
            heights = []
        if len(heights) == 4 and all(h >= 0 for h in heights):
            return heights
        print("four numbers >= 0, please", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """`python -m quadtank_tui.commands.daq rig ...`: the rig alone, through this
    module's own parser (the `quadtank` command builds cli.py's parser as well)."""
    parser = argparse.ArgumentParser(prog="python -m quadtank_tui.commands.daq")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    add_rig_parser(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args))
    except (OSError, ValueError) as exc:
        print(f"quadtank: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


# --- --daq for `quadtank` and `quadtank run` ------------------------------------------------

DAQ_HELP = ("Active mode through a DAQ: a DAQ configuration file (params/daq-labjack.yaml, "
            "params/virtual-rig.yaml) or a preset name (labjack)")


def add_daq_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup, *, dest: str = "daq") -> None:
    parser.add_argument("--daq", metavar="CONFIG", dest=dest, help=DAQ_HELP)


def _par_plant(par: str | None) -> Plant | None:
    """The plant of a .par file's PLANT section (None: the quadruple tank)."""
    if par is None:
        return None
    from quadtank_tui.files.par import read_par

    return read_par(par).params.process_plant()


def run_clock(*, realtime: bool, speed: float | None, config: str | None,
              plant: Plant | None = None
              ) -> tuple[Literal["realtime", "virtual", "manual"], ModbusBackend | IstBackend | None]:
    """The clock and the DAQ backend of `quadtank [--daq C] run [--daq C]`.  A real
    process is never run unpaced: with a DAQ the run is real time, unless --speed
    gives the virtual rig's speed factor."""
    daq = open_daq(config, plant, warn=warn)
    if realtime or (daq is not None and speed is None):
        return "realtime", daq
    return ("virtual" if speed is not None else "manual"), daq


if __name__ == "__main__":
    raise SystemExit(main())
