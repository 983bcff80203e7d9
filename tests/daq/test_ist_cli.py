"""`quadtank rig --protocol ist`, `quadtank daq check` and `quadtank run --daq` on
the virtual IST device, and the rig's lock (its serial device)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
import threading
from pathlib import Path
from typing import Callable, Iterator

import pytest

from quadtank_tui.cli import main
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.session import roles

pytestmark = pytest.mark.wallclock  # a device subprocess in real time

ROOT = Path(__file__).parents[2]
ME = roles.user_name(os.getuid())


class IstRig:
    """`quadtank rig --protocol ist --speed 10 --status 0.1` in a subprocess: its
    pty's path, and the status lines it prints (a thread reads them)."""

    def __init__(self) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "quadtank_tui", "rig", "--protocol", "ist", "--speed", "10", "--reset", "0.05",
             "--status", "0.1"], stdout=subprocess.PIPE, text=True, cwd=ROOT)
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        m = re.match(r"quadtank rig: IST device on (\S+) \(9600 8N1", line)
        assert m, line
        self.path = m.group(1)
        self.lines: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line)

    def stop(self) -> None:
        self.process.kill()
        self.process.wait()


@pytest.fixture(scope="module")
def ist_rig() -> Iterator[IstRig]:
    """One device for the module's tests (its start is a second of imports)."""
    rig = IstRig()
    try:
        yield rig
    finally:
        rig.stop()


def config_for(tmp_path: Path, port: str) -> Path:
    """params/daq-ist.yaml pointed at `port`, a shorter open wait (the device's reset is 0.05 s)."""
    text = (ROOT / "params" / "daq-ist.yaml").read_text()
    text = text.replace("port: /dev/ttyUSB0", f"port: {port}").replace("open_wait: 2.0", "open_wait: 0.5")
    path = tmp_path / "ist.yaml"
    path.write_text(text)
    return path


def test_daq_check_reads_the_levels_and_names_the_port_and_the_conversion(
        ist_rig: IstRig, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["daq", "check", str(config_for(tmp_path, ist_rig.path))]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"ist serial {ist_rig.path}  (9600 8N1, timeout 0.5 s, waited 0.5 s after opening")
    assert re.fullmatch(r"Vcc   code 26667   5\.0001 V", out[1])
    for i, line in enumerate(out[2:6], start=1):  # 6 V's levels (9.7-12.1 cm), drained or driven since
        m = re.fullmatch(rf"tank {i}  code +\d+ +\d\.\d{{4}} V  r = \d\.\d{{4}} +(\d+\.\d\d) cm  y = 0\.\d{{4}}", line)
        assert m and 3.0 < float(m.group(1)) < 14.0, line
    assert out[6].startswith("conversion: r = (Vcc - v) / v, h = dh_dr r + h0 (cm): tank1 -37.09 r + 43.42")
    assert out[7].startswith("watchdog: the firmware's own, 2 s")


def test_run_drives_the_device_and_its_disturbances_and_leaves_its_pumps_at_0(ist_rig: IstRig, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str],
                                                          poll: Callable[..., bool]) -> None:
    script = tmp_path / "exp.yaml"
    script.write_text('- at: 0\n  set: {"REFERENCE ONE.On": 1, "REFERENCE TWO.On": 1}\n'
                      '- at: 0\n  mode: Automatic\n- at: 0\n  log: on\n- at: 0\n  state: Run\n'
                      '- at: 3\n  disturbance: {d1: 1.0}\n- at: 6\n  disturbance: {d2: 0.5}\n')
    out = tmp_path / "active.log"
    status = main(["run", "--par", str(ROOT / "params" / "ist-lisbon.par"), "--daq",
                   str(config_for(tmp_path, ist_rig.path)), "--speed", "10", "--duration", "10",
                   "--script", str(script), "--log", str(out)])
    text = capsys.readouterr().out
    assert status == 0, text
    assert text.startswith("ran 10 s: ") and "FAULT" not in text
    log = read_log(out)
    # 10 slots at x10, the first ~5 gone in the open wait (0.5 s wall: the Nano's reset)
    assert 4 <= log.rows <= 10 and max(log.columns()["u1"]) > 0.3  # the PI drove the pumps
    assert "NOT confirmed" not in text
    def frames() -> list[str]:
        return [line.rstrip() for line in list(ist_rig.lines) if "pwm u =" in line]

    zero = "pwm u =    0    0  d =   0   0"
    # and stopped: the zero frame, in the rig's next status line (0.1 s; later on a busy machine)
    assert poll(lambda: frames()[-1].endswith(zero), 30.0), frames()[-3:]
    assert any(not line.endswith(zero) for line in frames())  # it pumped
    assert any(line.endswith("d = 255 128") for line in frames())  # the script's disturbances


def test_a_second_program_is_refused_naming_the_holder_of_the_port(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    port = tmp_path / "ttyFAKE"  # the lock is taken before the port is opened
    port.touch()
    code = textwrap.dedent(f"""
        import sys
        from quadtank_tui.session.lab import load_lab_config
        from quadtank_tui.session.lock import DaqLock
        DaqLock.acquire("serial:{os.path.realpath(port)}", load_lab_config())
        print("held", flush=True)
        sys.stdin.readline()
    """)
    child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdout.readline() == "held\n"
        log = tmp_path / "x.log"
        assert main(["run", "--daq", str(config_for(tmp_path, str(port))), "--duration", "1", "--log", str(log),
                     "--par", str(ROOT / "params" / "ist-lisbon.par")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"quadtank: error: the rig at serial:{os.path.realpath(port)} is driven by {ME} "
                              f"(pid {child.pid}) since ")
        assert not log.exists()
    finally:
        child.kill()
        child.wait()


def test_calibrate_write_is_refused_for_an_ist_file_in_one_line(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    cfg = config_for(tmp_path, "/dev/null")
    before = cfg.read_text()
    assert main(["daq", "calibrate", str(cfg), "--write", "--yes"]) == 2
    err = capsys.readouterr().err
    assert err == (f"quadtank: error: {cfg}: --write does not edit an IST file yet; copy the dh_dr and h0 lines "
                   "the fit prints into its calibration: section\n")
    assert cfg.read_text() == before


@pytest.mark.parametrize("par, body, error", [
    ("coupled-tito.par", "disturbance: {d1: 0.5}", "event 1 (line 1): the coupled-tito plant has no disturbance "
                                                   "pumps (the IST rig's pour into tanks 1 and 2 of the quadruple tank)"),
    ("ist-lisbon.par", "disturbance: {d3: 0.5}", "event 1 (line 1): disturbance needs {d1: 0..1, d2: 0..1} "
                                                 "(one may be left out)"),
    ("ist-lisbon.par", "disturbance: {d2: 1.5}", "event 1 (line 1): disturbance.d2 must be a number in 0..1 "
                                                 "(a fraction of full PWM), got 1.5"),
])
def test_a_disturbance_event_the_process_cannot_take_is_one_line(par: str, body: str, error: str, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    script = tmp_path / "d.yaml"
    script.write_text(f"- at: 1\n  {body}\n")
    assert main(["run", "--par", str(ROOT / "params" / par), "--script", str(script), "--duration", "3",
                 "--log", str(tmp_path / "d.log")]) == 2
    assert capsys.readouterr().err == f"quadtank: error: {script}, {error}\n"
