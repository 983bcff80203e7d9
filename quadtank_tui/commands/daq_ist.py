"""The IST rig's side of `quadtank rig --protocol ist`, `quadtank daq check` and
`daq calibrate`: commands/daq.py dispatches here on the configuration's
`protocol: ist`."""

from __future__ import annotations

import argparse
import contextlib
import sys
from typing import TYPE_CHECKING

from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import PlantParams, steady_state_levels
from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.ist.config import IstConfig, load_ist_config
from quadtank_tui.daq.ist.plant import IST_PLANT, IST_VOLTS
from quadtank_tui.engine.backend import BackendError

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant
    from quadtank_tui.daq.calibrate import Result


def cmd_rig_ist(args: argparse.Namespace) -> int:
    """`quadtank rig --protocol ist`: the virtual device on a new pseudo-terminal."""
    from quadtank_tui.daq.ist.device import Firmware, PtyDevice, serve

    if args.par is not None:
        from quadtank_tui.files.par import read_par

        params = read_par(args.par).params
        if params.process is not None:
            raise ValueError(f"--par {args.par}: the IST rig is a quadruple tank, not {params.process.kind}")
        plant, levels = params.quadtank_constants(), params.process_levels()
    else:
        plant, levels = IST_PLANT, steady_state_levels(IST_VOLTS, IST_PLANT)
    config = IstConfig(port="") if args.map in (None, "labjack") else load_ist_config(args.map)
    firmware = Firmware(config, plant, levels, speed=args.speed, reset_s=args.reset,
                        report=lambda text: print(f"quadtank rig: {text}", flush=True))
    device = PtyDevice(firmware)
    print(f"quadtank rig: IST device on {device.path} (9600 8N1; point port: of params/daq-ist.yaml at it)",
          flush=True)
    try:
        serve(device, status_every=args.status)
    except KeyboardInterrupt:
        pass
    finally:
        device.close()
    return 0


def cmd_check_ist(config: IstConfig) -> int:
    """`quadtank daq check` of an IST rig: one level request, nothing written."""
    from quadtank_tui.daq.ist.backend import IstBackend

    with contextlib.closing(IstBackend(config)) as backend:
        try:
            codes = backend.read_codes()
        except BackendError as exc:
            print(f"quadtank: {exc}", file=sys.stderr)
            return 1
    print(f"ist serial {config.port}  (9600 8N1, timeout {config.timeout:g} s, waited {config.open_wait:g} s "
          f"after opening; quadtank: 4 level, 2 pump channels)")
    print(f"Vcc   code {codes[4]:5d}  {p.adc_volts(codes[4]):7.4f} V")
    faults = 0
    for i, (s, code) in enumerate(zip(config.sensors, codes), start=1):
        lo, hi = config.plausible_range(i)
        try:
            r = p.ratio(code, codes[4])
        except p.FrameError as exc:
            print(f"tank {i}  code {code:5d}  SENSOR FAULT: {exc}")
            faults += 1
            continue
        h = s.level(r)
        mark = "" if lo <= h <= hi else f"  SENSOR FAULT: outside its plausible {lo:g}..{hi:g} cm"
        faults += bool(mark)
        print(f"tank {i}  code {code:5d}  {p.adc_volts(code):7.4f} V  r = {r:.4f}  {h:7.2f} cm  "
              f"y = {config.sensor_gain * h / FULL_SCALE_V:.4f}{mark}")
    print(config.conversion_line())
    print(f"watchdog: the firmware's own, {p.WATCHDOG_S:g} s without a level request stops all four pumps "
          "(fed by this program's samples and keep-alive; no guard process: the port is exclusive)")
    return 1 if faults else 0


def format_ist_result(result: Result, plant: PlantParams | Plant | None = None) -> str:
    """The fit of an IST rig: per tank h = dh_dr r + h0 as the file's lines, then the
    outlets (with the plant) as for any rig."""
    from quadtank_tui.daq.calibrate import format_result

    lines = ["# the sensors, h = dh_dr r + h0 (paste into the calibration: section of the IST file)"]
    lines += [f"  tank{i}: {{dh_dr: {cal.gain:.6g}, h0: {cal.offset:.6g}}}" for i, cal in sorted(result.sensors.items())]
    return "\n".join(lines) + "\n" + format_result(result, plant, config_lines=False)
