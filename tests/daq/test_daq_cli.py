"""`quadtank daq check CONFIG` (read-only) and `quadtank daq fit VOLTS:CM ...`."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.cli import main
from quadtank_tui.daq.modbus import ModbusBackend
from daqkit import rig_yaml

ROOT = Path(__file__).parents[2]


def test_fit_prints_desautel_sensor_1_and_a_config_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["daq", "fit", "0.5864:3.5", "1.3422:7.5", "2.2396:12.25", "3.2051:17.75", "--tank", "3"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == ["gain 5.4310 cm/V  offset 0.2390 cm  rms residual 0.101 cm",
                   "  tank3: {gain: 5.4310, offset: 0.2390}"]


@pytest.mark.parametrize(("pairs", "message"), [(["1:2", "x"], "'x': expected VOLTS:CM"),
                                                (["1:2"], "at least two"), (["1:2", "1:3"], "same voltage")])
def test_fit_refuses_bad_pairs(pairs: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["daq", "fit", *pairs]) == 2
    assert message in capsys.readouterr().err


def test_check_reads_and_writes_nothing(rig: Callable, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = rig()
    config = tmp_path / "rig.yaml"
    config.write_text(rig_yaml(r.port))
    driver = ModbusBackend(r.config())
    driver.write_pumps((0.25, 0.35))
    assert main(["daq", "check", str(config)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith(f"modbus 127.0.0.1:{r.port}")
    assert [ln.split()[:3] for ln in lines[1:5]] == [["tank", str(i), f"AIN{i - 1}"] for i in range(1, 5)]
    assert lines[5:] == ["watchdog: enable at holding register 61600, timeout (auto) at 61604, "
                         "sets DAC0/DAC1 to stop their pumps; strict: only this program's feed with its key "
                         "clears it",  # the LabJack's, which check leaves alone
                         "rig identity: the virtual rig's pump amplifiers and sensors are this file's"]
    assert r.dacs() == pytest.approx((2.5, 3.5))  # the pumps were left alone
    driver.safe_state()
    driver.close()


def test_check_without_a_device_says_why(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    with socket.socket() as s:  # bound, never listening: refused, and no other test's port meanwhile
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        config = tmp_path / "rig.yaml"
        config.write_text(f"host: 127.0.0.1\nport: {port}\n")
        assert main(["daq", "check", str(config)]) == 1
    assert "cannot connect" in capsys.readouterr().err


def test_check_refuses_a_file_whose_amplifier_the_virtual_rig_does_not_have(
        rig: Callable, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The README's old tour: params/daq-labjack.yaml (pump amplifier gain 2) against
    `quadtank rig` (the LabJack preset: gain 1): the program would write 1.5 V for 3
    V and the rig apply 1.5 V. One line, exit 2; Active control is refused alike."""
    r = rig()
    text = (ROOT / "params" / "daq-labjack.yaml").read_text()
    assert "host: 192.168.1.207" in text and "port: 502 " in text
    config = tmp_path / "labjack.yaml"
    config.write_text(text.replace("host: 192.168.1.207", "host: 127.0.0.1").replace("port: 502 ", f"port: {r.port} "))
    assert main(["daq", "check", str(config)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"quadtank: {config}: not the rig at 127.0.0.1:{r.port}: ")
    assert "pump1 gain 2 (the rig's 1), pump2 gain 2 (the rig's 1)" in err[0]
    from quadtank_tui.daq.open import load_rig_config

    backend = ModbusBackend(load_rig_config(config))  # type: ignore[arg-type]
    try:
        why = backend.identity_refused()
    finally:
        backend.close()
    assert why is not None and "pump1 gain 2 (the rig's 1)" in why
