"""A headless run whose interlock held the pumps at 0 says so and exits 3.

The virtual rig's registers are served in this process (VirtualRig on a manual
clock the loop's samples move: no socket, no wall time), behind the real
ModbusBackend and its interlock: tank 1 starts at 18 cm of 20 and pump 1 is asked
for 9 V, so the tank overflows again and again.  The summary names the tank, the
pump, the samples held and when; the log holds the pump values really written
(0 while held, as the rig's registers have them), with a `%` line at each trip
and release; `run --detach`'s session says it too."""

from __future__ import annotations

import io
import re
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from quadtank_tui.daq.config import DaqConfig, load_daq_config
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.daq.rig import VirtualRig
from quadtank_tui.engine.headless import INTERLOCK_ACTED, prepare_headless, run_headless
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.files.par import read_par
from quadtank_tui.files.script import read_script
from quadtank_tui.engine.driver import Driver
from quadtank_tui.session.scripted import ScriptedRun

ROOT = Path(__file__).parents[2]
PAR = ROOT / "params" / "default.par"


class RigHere(ModbusBackend):
    """ModbusBackend on a VirtualRig's registers in this process; the rig's time
    advances by the loop's sampling time at each sample (elapse)."""

    def __init__(self, config: DaqConfig, levels_cm: tuple[float, float, float, float]) -> None:
        super().__init__(config, guard=False)
        self.now = 0.0
        params = read_par(PAR).params
        self.rig = VirtualRig(config, params.quadtank_constants(), levels_cm, clock=lambda: self.now)
        self.pump1_volts: list[float] = []  # the rig's pump 1 after each write

    def _request(self, what, call):
        return call()

    def _read(self, table: str, first: int, count: int) -> list[int]:
        return self.rig.read(first, count)

    def _write(self, address: int, values: list[int]) -> list[int]:
        self.rig.write(address, values)
        if address == self.config.pump_output(1).register.address:  # not the watchdog's settings
            self.pump1_volts.append(self.rig.pump_volts[0])
        return values

    def elapse(self, dt: float) -> None:
        self.now += dt


@pytest.fixture
def overflowing(tmp_path: Path) -> tuple[RigHere, Path]:
    config = load_daq_config(ROOT / "params" / "virtual-rig.yaml", read_par(PAR).params.process_plant())
    script = tmp_path / "overflow.yaml"
    script.write_text("- {at: 0, state: Run}\n- {at: 0, set: {REFERENCE ONE.Mean: 0.9}}\n")
    return RigHere(config, (18.0, 10.0, 5.0, 5.0)), script


def test_the_summary_says_what_the_interlock_held_and_the_run_exits_3(
        overflowing: tuple[RigHere, Path], tmp_path: Path) -> None:
    backend, script = overflowing
    out = tmp_path / "overflow.log"
    result = run_headless(par=str(PAR), script=read_script(str(script)), duration=30.0, out=out,
                          clock="manual", daq=backend)
    assert result.status == INTERLOCK_ACTED == 3
    held = [line for line in result.text.splitlines() if line.startswith("INTERLOCK")]
    assert len(held) == 1, result.text
    m = re.fullmatch(r"INTERLOCK  tank 1 above 95 % of its height: pump 1 held at 0 in (\d+) samples "
                     r"\(([\d.]+) s\), t = ([\d.]+) \.\. ([\d.]+) s, (\d+) trips(; still holding at the end)?",
                     held[0])
    assert m is not None, held[0]
    samples, trips = int(m[1]), int(m[5])
    assert float(m[2]) == pytest.approx(samples * 0.1)

    log = read_log(out)
    cols = log.columns()
    assert log.rows == 300
    # The log has what the rig was given: u1 = 0 exactly at the held samples, 0.9 otherwise.
    assert [round(10 * u, 9) for u in cols["u1"]] == backend.pump1_volts[:300]
    zero = [round(k * 0.1, 9) for k, u in enumerate(cols["u1"]) if u == 0.0]  # t = k TSamp
    assert set(cols["u1"]) == {0.0, 0.9}
    assert len(zero) == samples and 10 < samples < 300
    assert (zero[0], zero[-1]) == (pytest.approx(float(m[3])), pytest.approx(float(m[4])))
    text = out.read_text()
    assert text.count("interlock: tank 1 above 95 % of its height, pump 1 cut") == trips > 1
    released = text.count("interlock: tank 1 released")
    assert released == (trips - 1 if m[6] else trips)
    assert "% t = " + f"{float(m[3]):g} s: interlock: tank 1 above 95 %" in text


def test_a_run_the_interlock_never_touched_exits_0(overflowing: tuple[RigHere, Path], tmp_path: Path) -> None:
    backend, script = overflowing
    backend.rig.h = (5.0, 5.0, 2.0, 2.0)
    script.write_text("- {at: 0, state: Run}\n")  # u = 0.3: nowhere near the limit in 10 s
    result = run_headless(par=str(PAR), script=read_script(str(script)), duration=10.0,
                          out=tmp_path / "calm.log", clock="manual", daq=backend)
    assert result.status == 0 and "INTERLOCK" not in result.text
    assert "interlock" not in (tmp_path / "calm.log").read_text()


def test_a_detached_runs_summary_says_it_too(overflowing: tuple[RigHere, Path], tmp_path: Path) -> None:
    backend, script = overflowing
    out = tmp_path / "detached.log"
    prepared = prepare_headless(par=str(PAR), script=read_script(str(script)), duration=20.0, out=out,
                                clock="manual", daq=backend)
    run = ScriptedRun(prepared)
    try:
        Driver(prepared.engine, duration=run.duration, before=run.before).run()  # as the session drives it
        printed = io.StringIO()
        with redirect_stdout(printed):
            reason = run.finish()
    finally:
        prepared.engine.stop()
    assert reason == f"the run is over; its log is {out}; the interlock held pumps at 0 (see its output)"
    assert re.search(r"^INTERLOCK  tank 1 above 95 % of its height: pump 1 held at 0 in \d+ samples",
                     printed.getvalue(), re.M)


class CutCable(RigHere):
    """The link dies after `good` writes: every request fails from then on."""

    def __init__(self, config: DaqConfig, levels_cm: tuple[float, float, float, float], good: int) -> None:
        super().__init__(config, levels_cm)
        self.good = good

    def _read(self, table: str, first: int, count: int) -> list[int]:
        if len(self.pump1_volts) >= self.good:
            raise OSError("cable cut")
        return super()._read(table, first, count)

    def _write(self, address: int, values: list[int]) -> list[int]:
        if len(self.pump1_volts) >= self.good:
            raise OSError("cable cut")
        return super()._write(address, values)


def test_pumps_not_confirmed_at_0_are_said_and_the_run_exits_1(tmp_path: Path) -> None:
    """After a fault the loop commands the pumps to 0; when that cannot be confirmed
    (the link is gone) the summary says so, beside the fault."""
    config = load_daq_config(ROOT / "params" / "virtual-rig.yaml", read_par(PAR).params.process_plant())
    backend = CutCable(config, (5.0, 5.0, 2.0, 2.0), good=20)
    result = run_headless(par=str(PAR), script=None, duration=5.0, out=tmp_path / "cut.log", clock="manual",
                          daq=backend)
    assert result.status == 1
    lines = result.text.splitlines()
    assert any(line.startswith("FAULT      modbus 127.0.0.1:5020: OSError: cable cut") for line in lines), lines
    assert lines[-1] == ("PUMPS      NOT confirmed at 0 (left to the device's watchdog to stop them): "
                         "OSError: cable cut; OSError: cable cut")
    assert read_log(tmp_path / "cut.log").rows == 20
    assert backend.rig.pump_volts == (3.0, 3.0)  # indeed still running, as the line says


class ZeroRefused(RigHere):
    """The device refuses every write of 0 V to the pump outputs (busy at each)."""

    def _write(self, address: int, values: list[int]) -> list[int]:
        pumps = [self.config.pump_output(i).register for i in (1, 2)]
        if address in [r.address for r in pumps] and \
                all(v == 0 for v in values):  # 0.0 as FLOAT32 is all-zero words
            raise OSError("device busy")
        return super()._write(address, values)


def test_a_run_whose_last_write_of_0_fails_says_so_after_the_stop_and_exits_1(tmp_path: Path) -> None:
    """The run goes well; the engine's stop at its end cannot put the pumps at 0:
    the summary (written after the stop) says so and the run exits 1.  Before, the
    summary was written before the stop and said nothing: status 0, pumps at 3 V."""
    config = load_daq_config(ROOT / "params" / "virtual-rig.yaml", read_par(PAR).params.process_plant())
    backend = ZeroRefused(config, (5.0, 5.0, 2.0, 2.0))
    result = run_headless(par=str(PAR), script=None, duration=2.0, out=tmp_path / "busy.log", clock="manual",
                          daq=backend)
    assert result.status == 1
    assert result.text.splitlines()[-1] == (
        "PUMPS      NOT confirmed at 0 (left to the device's watchdog to stop them): OSError: device busy; "
        "OSError: device busy")
    assert backend.rig.pump_volts == (3.0, 3.0)      # indeed still running, as the line says
    assert backend.rig.watchdog is not None and backend.rig.watchdog.enabled  # left armed: it stops them
