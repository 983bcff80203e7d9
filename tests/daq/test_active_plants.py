"""Active mode on a two-tank plant end to end (issue 14): the virtual rig serves the
cascade (Desautel's CTP) through a DAQ map read for it, `quadtank run --daq` runs the
coupled-cascade preset on it, and the log's columns carry the plant's levels: y1, y2
the two tanks' sensors (kc_i x_i / 10 V), u1 the one pump, u2 never written."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest
from pymodbus.client import ModbusTcpClient

from quadtank_tui.cli import main
from quadtank_tui.core.plants import CoupledCascade, CoupledTITO, QuadTank
from quadtank_tui.daq.config import load_daq_config
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.daq.registers import decode
from quadtank_tui.engine.runner import build_engine
from quadtank_tui.files.log_reader import read_log
from daqkit import rig_yaml

ROOT = Path(__file__).parents[2]
CASCADE_PAR = ROOT / "params" / "coupled-cascade.par"
TITO_PAR = ROOT / "params" / "coupled-tito.par"
COUPLED_MAP = ROOT / "params" / "virtual-rig-coupled.yaml"
#: Desautel's operating point x1 = 15 cm: u = alpha1 sqrt(2 g x1) / beta1 = 6.769 V of
#: the 22 V amplifier (the preset's Manual input 0.307692), x2 = (alpha1/alpha2)^2 x1.
X1, X2 = 15.0, 14.7273938035591
STEP = """\
- at: 0
  log: on
- at: 0
  state: Run
- at: 5
  set: {"REFERENCE ONE.Mean": 0.4}
"""


def coupled_map(tmp_path: Path, port: int) -> Path:
    path = tmp_path / "coupled.yaml"
    path.write_text(rig_yaml(port, COUPLED_MAP))
    return path


def holding(port: int, address: int, count: int) -> list[int] | None:
    """Registers read by a client of our own; None when the rig has no such register."""
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=2.0)
    try:
        rr = client.read_holding_registers(address, count=count, device_id=1)
        return None if rr.isError() else list(rr.registers)
    finally:
        client.close()


def test_the_backend_reads_two_levels_and_drives_one_pump(rig: Callable, tmp_path: Path) -> None:
    r = rig("--map", str(COUPLED_MAP), "--par", str(CASCADE_PAR), "--watchdog", "0", "--speed", "0.001")
    p = CoupledCascade()
    backend = ModbusBackend(load_daq_config(coupled_map(tmp_path, r.port), p))
    try:
        y = backend.read_levels()
        assert y[:2] == pytest.approx((p.kc1 * X1 / 10, p.kc2 * X2 / 10), abs=1e-5) and y[2:] == (0.0, 0.0)
        assert backend.read_raw_volts() == pytest.approx((p.kc1 * X1, p.kc2 * X2), abs=1e-4)
        backend.write_pumps((0.5, 0.9))  # the cascade has no pump 2: u2 goes nowhere
        dac0 = load_daq_config(COUPLED_MAP, p).pump_output(1).register
        assert decode(dac0, holding(r.port, 1000, 2) or []) == pytest.approx(5.0, abs=1e-6)
        assert holding(r.port, 1002, 2) is None  # no DAC1 on a one-pump rig
        backend.safe_state()
        assert backend.safe_state_error == "" and decode(dac0, holding(r.port, 1000, 2) or []) == 0.0
    finally:
        backend.close()
    assert backend.plant_refused(p) is None
    assert "wired for the coupled-cascade plant" in (backend.plant_refused(QuadTank()) or "")


def test_the_two_input_rig_drives_both_pumps(rig: Callable, tmp_path: Path) -> None:
    """Murray-Smith's rig: two levels in metres (y = Gd H / 10 V), two pumps."""
    r = rig("--map", str(COUPLED_MAP), "--par", str(TITO_PAR), "--watchdog", "0", "--speed", "0.001")
    backend = ModbusBackend(load_daq_config(coupled_map(tmp_path, r.port), CoupledTITO()))
    try:
        assert backend.read_levels() == pytest.approx((33.33 * 0.115 / 10, 33.33 * 0.071 / 10, 0.0, 0.0), abs=1e-5)
        backend.write_pumps((0.3, 0.2))
        dac = load_daq_config(COUPLED_MAP, CoupledTITO()).pump_output(1).register
        words = holding(r.port, 1000, 4) or []
        assert (decode(dac, words[:2]), decode(dac, words[2:])) == pytest.approx((3.0, 2.0), abs=1e-6)
    finally:
        backend.safe_state()
        backend.close()


def test_daq_check_reads_the_plants_channels(rig: Callable, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """Two tanks of the two-input rig at Murray-Smith's operating point, in metres."""
    r = rig("--map", str(COUPLED_MAP), "--par", str(TITO_PAR), "--watchdog", "0", "--speed", "0.001")
    assert main(["daq", "check", str(coupled_map(tmp_path, r.port)), "--par", str(TITO_PAR)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith("coupled-tito: 2 level, 2 pump channels)")
    assert [ln.split()[:6] for ln in lines[1:-2]] == [
        ["tank", "1", "AIN0", f"{33.33 * 0.115:.4f}", "V", "0.1150"],
        ["tank", "2", "AIN1", f"{33.33 * 0.071:.4f}", "V", "0.0710"]]
    assert lines[-2].startswith("watchdog: enable at holding register 61600")
    assert lines[-1] == "rig identity: the virtual rig's pump amplifiers and sensors are this file's"


def test_an_engine_on_a_daq_of_another_plant_is_refused() -> None:
    """A backend read for the quadruple tank under the cascade's parameters (the
    program reads the configuration for the plant; a mix-up still stops here)."""
    backend = ModbusBackend(load_daq_config("labjack"))
    with pytest.raises(ValueError, match="wired for the quadtank plant, but the plant in use is coupled-cascade"):
        build_engine(CASCADE_PAR, daq=backend, clock="manual")


# alone (tests/conftest.py): the run is paced on the wall at x20 beside a rig whose time
# does not wait, so a stall of the run's process shows in the levels compared (1.5 s of
# wall time); beside another wallclock test at load 7-9 the upper tank ended 0.0096 high.
@pytest.mark.alone
def test_run_daq_on_the_cascade_logs_the_plants_columns(rig: Callable, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """The same scripted step (u 0.3077 -> 0.4 at t = 5 s) on the simulator and on
    the rig: each log's last levels (t = 29.9 s) are the plant's own ZOH response
    from the row where the step came (t = 5 s; the rig's tanks drained a little
    while the run started, its pumps were off), in the plant's sensor units."""
    r = rig("--map", str(COUPLED_MAP), "--par", str(CASCADE_PAR), "--speed", "20")
    script = tmp_path / "step.yaml"
    script.write_text(STEP)
    common = ["--par", str(CASCADE_PAR), "--script", str(script), "--duration", "30"]
    active, simul = tmp_path / "active.log", tmp_path / "simul.log"
    status = main(["run", "--daq", str(coupled_map(tmp_path, r.port)), "--speed", "20", "--log", str(active), *common])
    text = capsys.readouterr().out
    assert status == 0, text
    assert main(["run", "--log", str(simul), *common]) == 0
    a, s = read_log(active).columns(), read_log(simul).columns()
    p = CoupledCascade()
    assert (s["y1"][0], s["y2"][0]) == pytest.approx((p.kc1 * X1 / 10, p.kc2 * X2 / 10), abs=1e-6)
    for log, slack in ((s, 1e-5), (a, 3e-3)):
        assert set(log["u2"]) == {0.0} and log["u1"][0] == pytest.approx(0.307692)
        assert log["u1"][-1] == pytest.approx(0.4)
        k = next(i for i, u in enumerate(log["u1"]) if u == pytest.approx(0.4))
        x = p.advance((10 * log["y1"][k] / p.kc1, 10 * log["y2"][k] / p.kc2), (0.4 * 22.0,), 29.9 - 5.0)
        # the rig's time does not wait for a busy machine: a sample or two of slack
        assert (log["y1"][-1], log["y2"][-1]) == pytest.approx((p.kc1 * x[0] / 10, p.kc2 * x[1] / 10), abs=slack)
    assert a["y1"][-1] > a["y1"][0] + 0.02  # the step moved the upper tank


def test_run_daq_with_a_four_tank_map_on_the_cascade_names_the_extra_keys(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig_map = ROOT / "params" / "virtual-rig.yaml"
    status = main(["run", "--daq", str(rig_map), "--par", str(CASCADE_PAR), "--duration", "1",
                   "--speed", "20", "--log", str(tmp_path / "x.log")])
    assert status == 2
    assert capsys.readouterr().err.strip() == (
        f"quadtank: error: {rig_map}:22: calibration.tank3: tank3, tank4, pump2 are extra: a coupled-cascade "
        "plant has 2 level channels (tank1, tank2) and 1 pump channel (pump1)")


def test_loading_another_plants_par_under_a_daq_is_refused() -> None:
    """The TUI on a quadruple-tank rig: params/coupled-cascade.par is refused with the
    reason, and the parameters in use stay."""
    from quadtank_tui.engine.commands import LoadPar

    engine = build_engine(ROOT / "params" / "default.par", daq=ModbusBackend(load_daq_config("labjack")),
                          clock="manual", params_dir=ROOT / "params")
    before = engine.params
    result = engine.submit(LoadPar("coupled-cascade")).result()
    assert not result.ok
    assert result.message == (
        "PLANT.Kind: preset labjack: wired for the quadtank plant, but the "
        "plant in use is coupled-cascade: a coupled-cascade plant has 2 level channels (tank1, tank2) and 1 pump "
        "channel (pump1); read the configuration for it")
    assert engine.params == before


def test_the_tui_reads_its_daq_for_the_par_plant() -> None:
    """`quadtank --par coupled-cascade.par --daq virtual-rig-coupled.yaml`: the loop
    process gets the backend wired for the cascade and offers Active."""
    from quadtank_tui.cli import build_parser
    from quadtank_tui.commands.tui import build_tui

    args = ["--par", str(CASCADE_PAR), "--daq", str(COUPLED_MAP)]
    engine, _app = build_tui(build_parser().parse_args(args))
    try:
        snap = engine.snapshot()
        assert snap.active_available and snap.params.process is not None
        assert snap.params.process.kind == "coupled-cascade"
    finally:
        engine.stop()
