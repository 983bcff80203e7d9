"""The IST rig through a session (the TUI's path), against the simulator.

    .venv/bin/python benchmarks/ist_session.py [--seconds 90] [--kills 3]

1. A session process started as `quadtank --par params/ist-lisbon.par --daq
   daq-ist.yaml` starts it, on the virtual IST device (daq/ist/device.py, served by
   a thread of this process on a pseudo-terminal, the wall clock): Active, Manual,
   u1 a square wave 0.5..0.7 (period 40 s), u2 at 0.6, for `--seconds` at Ts 1 s.
   The session's history (levels read from the device's codes, the inputs written
   as PWM frames) is then replayed on the simulator from the first levels read, with
   the same inputs sample by sample: max and RMS |y difference| in cm per tank.
   What differs is the rig's own: the converters' quantization, the 10-bit PWM of the
   identified pump law, and the wall-clock jitter of the samples.
2. `--kills` times: a detached session on the device, Active and pumping, SIGKILLed;
   the time until the device's pumps are at 0 (its 2 s watchdog, fed by the session's
   last level request).

Figures are printed, not asserted (the machine may be shared).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).parents[1]
sys.path.insert(0, str(ROOT))

from quadtank_tui.core.plants.johansson import steady_state_levels  # noqa: E402
from quadtank_tui.daq.ist.config import IstConfig  # noqa: E402
from quadtank_tui.daq.ist.device import Firmware, ServedDevice  # noqa: E402
from quadtank_tui.engine.commands import SetOperation, SetParams, SetState  # noqa: E402
from quadtank_tui.engine.runner import engine_spec  # noqa: E402
from quadtank_tui.engine.sim import SimBackend  # noqa: E402
from quadtank_tui.files.par import read_par  # noqa: E402
from quadtank_tui.session.client import SessionClient, stop_session_at  # noqa: E402
from quadtank_tui.session.launch import SessionSpec, start_session  # noqa: E402

PAR = ROOT / "params" / "ist-lisbon.par"
PLANT = read_par(PAR).params.quadtank_constants()  # the session's, the device's and the replay's
WAVE = {"REFERENCE ONE.On": 1, "REFERENCE ONE.Mean": 0.6, "REFERENCE ONE.Amplitude": 0.1,
        "REFERENCE ONE.Period": 40.0, "REFERENCE TWO.On": 0, "REFERENCE TWO.Mean": 0.6}


def serve_device() -> ServedDevice:
    return ServedDevice(Firmware(IstConfig(port=""), PLANT, steady_state_levels((6.0, 6.0), PLANT), reset_s=0.05))


def config_file(folder: Path, port: str) -> Path:
    text = (ROOT / "params" / "daq-ist.yaml").read_text()
    path = folder / "ist.yaml"
    path.write_text(text.replace("port: /dev/ttyUSB0", f"port: {port}").replace("open_wait: 2.0", "open_wait: 0.1"))
    return path


def active_session(folder: Path, cfg: Path) -> tuple[SessionClient, str, int]:
    spec = engine_spec(PAR, clock="realtime", params_dir=folder / "params", logs_dir=folder / "logs")
    info = start_session(SessionSpec(spec, str(folder / "run"), str(cfg)))
    client = SessionClient(info.socket)
    for command in (SetOperation("Active"), SetParams(WAVE), SetState("Run")):
        result = client.submit(command).result(timeout=30)
        assert result.ok, result.message
    return client, info.socket, info.pid


def compare(seconds: float) -> None:
    device = serve_device()
    try:
        with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:
            folder = Path(tmp)
            client, socket, _ = active_session(folder, config_file(folder, device.path))
            time.sleep(seconds)
            hist = client.history()
            stop_session_at(socket)
            client.close()
    finally:
        device.close()
    n = len(hist["t"])
    kc = PLANT.kc
    y = np.column_stack([hist[f"y{i}"] for i in range(1, 5)])
    u = np.column_stack([hist["u1"], hist["u2"]])
    sim = SimBackend(PLANT, tuple(float(v) * 10.0 / kc for v in y[0]))
    replay = [sim.read_levels()]
    for k in range(n - 1):
        sim.write_pumps((float(u[k, 0]), float(u[k, 1])))
        sim.elapse(1.0)
        replay.append(sim.read_levels())
    diff_cm = (y - np.array(replay)) * 10.0 / kc
    print(f"1. session on the pty device vs the simulator: {n} samples at Ts 1 s, u1 square 0.5..0.7, u2 0.6")
    print(f"   swing of y1 on the device: {np.ptp(y[:, 0]) * 10 / kc:.2f} cm")
    for i in range(4):
        d = diff_cm[:, i]
        print(f"   tank {i + 1}: max |diff| {np.max(np.abs(d)):.3f} cm, RMS {np.sqrt(np.mean(d ** 2)):.3f} cm")


def kill_times(kills: int) -> None:
    took = []
    for _ in range(kills):
        device = serve_device()
        firmware = device.firmware
        try:
            with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:
                folder = Path(tmp)
                client, socket, pid = active_session(folder, config_file(folder, device.path))
                client.close()  # detached: no client to rescue the pumps
                deadline = time.monotonic() + 30
                while firmware.pwm[0] == 0 and time.monotonic() < deadline:
                    time.sleep(0.01)
                time.sleep(1.0 + np.random.default_rng().uniform(0, 1.0))  # anywhere in a sample
                assert firmware.pwm[0] > 0, "the session stopped pumping before the kill"
                os.kill(pid, signal.SIGKILL)
                t0 = time.monotonic()
                while firmware.pwm != (0, 0, 0, 0) and time.monotonic() < t0 + 10:
                    time.sleep(0.005)
                took.append(time.monotonic() - t0)
        finally:
            device.close()
    print("2. SIGKILL of an Active session -> the device's pumps at 0: "
          + ", ".join(f"{t:.2f}" for t in took) + " s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=90.0)
    parser.add_argument("--kills", type=int, default=3)
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="quadtank-bench-"))
    os.environ["QUADTANK_RUNTIME"] = str(folder / "run")
    # a lab whose unattended Active sessions keep running (else a detached one pauses, pumps at 0)
    (folder / "lab.yaml").write_text("unattended:\n  grace_minutes: 10\n")
    os.environ["QUADTANK_LAB"] = str(folder / "lab.yaml")
    compare(args.seconds)
    kill_times(args.kills)


if __name__ == "__main__":
    main()
