"""The DAQ's own watchdog: declared by the configuration, armed by Active control,
disarmed at an orderly end, and a silence longer than its timeout ending Active
control.  In process: a virtual rig on the test's clock behind our Modbus server."""

from __future__ import annotations

from typing import Any, Callable, Literal, Sequence

import pytest

from quadtank_tui.commands.sessions import format_table
from quadtank_tui.core.plants.johansson import P_MINUS
from quadtank_tui.daq.config import DaqConfigError, load_daq_config, parse_daq_config
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.daq.registers import Register
from quadtank_tui.daq.rig import VirtualRig
from quadtank_tui.engine.backend import BackendError
from quadtank_tui.session.info import SessionInfo
from daqkit import VIRTUAL_RIG, recording_guard

U32: Literal["uint32"] = "uint32"


def test_the_labjack_preset_declares_the_t_series_watchdog_registers() -> None:
    """The addresses of LabJack's Modbus map (T-Series datasheet 23.0)."""
    wd = load_daq_config("labjack").watchdog
    assert wd is not None
    assert wd.enable == Register("holding", 61600, U32)           # WATCHDOG_ENABLE_DEFAULT
    assert wd.timeout_register == Register("holding", 61604, U32)  # WATCHDOG_TIMEOUT_S_DEFAULT
    assert wd.feed == Register("holding", 61614, U32)             # WATCHDOG_STRICT_CLEAR
    assert wd.strict_enable == Register("holding", 61610, U32)    # WATCHDOG_STRICT_ENABLE_DEFAULT
    assert wd.strict_key == Register("holding", 61612, U32)       # WATCHDOG_STRICT_KEY_DEFAULT
    assert [(a.output, a.enable, a.value) for a in wd.actions] == [
        ("DAC0", Register("holding", 61640, U32), Register("holding", 61642, "float32")),
        ("DAC1", Register("holding", 61650, U32), Register("holding", 61652, "float32"))]
    # a few samples, at least 1 s, in the whole seconds the register holds
    assert [wd.timeout_for(ts) for ts in (0.01, 0.1, 0.5, 0.7, 10.0)] == [1.0, 1.0, 1.0, 2.0, 20.0]


@pytest.mark.parametrize("section, message", [
    ("watchdog:\n  timeout: soon\n", "x.yaml:4: watchdog.timeout: must be a number, got 'soon'"),
    ("watchdog:\n  enable: {address: 1002}\n",
     "x.yaml:4: watchdog.enable.address: holding register 1002 is also used by outputs.DAC1"),
    ("watchdog:\n  outputs: {DAC9: {value: {address: 7}}}\n",
     "x.yaml:4: watchdog.outputs.DAC9: DAC9 is not one of the outputs (DAC0, DAC1)"),
    ("watchdog: [61600]\n", "x.yaml:3: watchdog: must be the device's watchdog registers (a mapping) or none, "
                            "got [61600]"),
])
def test_a_bad_watchdog_section_is_refused_with_file_line_and_key(section: str, message: str) -> None:
    with pytest.raises(DaqConfigError) as err:
        parse_daq_config("preset: labjack\nhost: 10.0.0.2\n" + section, name="x.yaml")
    assert str(err.value) == message


def test_a_device_without_one_is_said_to_have_none(capsys: pytest.CaptureFixture[str]) -> None:
    plc = load_daq_config("params/daq-plc-example.yaml")
    assert plc.watchdog is None
    assert plc.watchdog_line() == ("watchdog: none declared by params/daq-plc-example.yaml: if this program dies "
                                   "its guard stops the pumps; if the computer dies or hangs, nothing does")
    from quadtank_tui.commands.daq import run_clock
    from quadtank_tui.daq.open import open_daq

    open_daq("params/daq-plc-example.yaml")  # the DAQ layer prints nothing itself
    assert capsys.readouterr().err == ""
    said: list[str] = []
    open_daq("params/daq-plc-example.yaml", warn=said.extend)
    assert said == [plc.watchdog_line()]
    # a command says it once, as its other warnings, on stderr
    run_clock(realtime=True, speed=None, config="params/daq-plc-example.yaml")
    assert capsys.readouterr() == ("", f"quadtank: warning: {plc.watchdog_line()}\n")
    info = SessionInfo(id="ann-1", owner="ann", uid=1000, pid=1, started="2026-11-26T10:00:00", plant="quadtank",
                       operation="Active", daq="params/daq-plc-example.yaml", watchdog="none")
    assert "  Active (no watchdog)  " in format_table([info])


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _rig_and_backend(device: Callable[..., Any]) -> tuple[Clock, VirtualRig, ModbusBackend, list[int]]:
    clock = Clock()
    config = load_daq_config(VIRTUAL_RIG)
    rig = VirtualRig(config, P_MINUS.params, P_MINUS.op.x, clock=clock)
    written: list[int] = []
    write = rig.write

    def recorded(address: int, values: Sequence[int]) -> None:
        written.append(address)
        write(address, values)

    rig.write = recorded  # type: ignore[method-assign]  # the writes the backend makes, in order
    d = device((0.0,) * 4, bank=rig)
    return clock, rig, ModbusBackend(d.config(), clock=clock, guard=False), written


def test_active_control_arms_the_watchdog_and_an_orderly_end_disarms_it(device: Callable[..., Any]) -> None:
    clock, rig, backend, written = _rig_and_backend(device)
    wd = rig.watchdog
    assert wd is not None and not wd.enabled          # off out of the box
    backend.arm(0.7)                                  # 2 Ts = 1.4 s: 2 whole seconds
    backend.write_pumps((0.3, 0.3))
    assert wd.enabled and wd.timeout == 2.0 and wd.actions() == [("DAC0", 0.0), ("DAC1", 0.0)]
    # the settings that differ (the values on timeout are 0 V already: strict mode, the
    # run's key), then on, then the pumps
    assert written == [61604, 61610, 61612, 61640, 61650, 61600, 1000]
    clock.now += 1.9                                  # traffic within the timeout: quiet
    backend.read_levels()
    clock.now += 1.9
    rig.tick()
    assert rig.pump_volts == (3.0, 3.0)
    clock.now += 0.2                                  # 2.1 s of silence: the device stops the pumps
    rig.tick()
    assert rig.pump_volts == (0.0, 0.0) and rig.watchdog_trips == 1
    backend.close()
    assert not wd.enabled
    written.clear()
    backend.arm(0.7)                                  # armed again: only the enable differs (flash)
    backend.read_levels()
    assert written == [61600] and wd.enabled
    backend.read_levels()
    assert written == [61600]                         # arming has just cleared the timer: no feed yet
    clock.now += 0.6
    backend.read_levels()
    assert written == [61600, 61614]                  # the feed, as often as a quarter of the timeout
    backend.safe_state()
    backend.close()


def test_a_silence_longer_than_the_timeout_ends_active_control(device: Callable[..., Any]) -> None:
    """The program stopped (SIGSTOP) or the machine suspended: the next sample is
    refused, never a silent return to the outputs of before."""
    clock, rig, backend, _ = _rig_and_backend(device)
    backend.arm(0.1)
    backend.write_pumps((0.3, 0.3))
    clock.now += 0.9
    backend.read_levels()                             # 0.9 s: within the 1 s timeout
    clock.now += 32.9
    with pytest.raises(BackendError, match=r"^no request reached the rig for 32\.9 s, longer than the watchdog "
                       r"timeout 1 s .*its watchdog has set the pumps to 0\. Active control ends here"):
        backend.write_pumps((0.3, 0.3))
    rig.tick()
    assert rig.pump_volts == (0.0, 0.0)              # the device's watchdog did meanwhile
    backend.safe_state()
    backend.write_pumps((0.3, 0.3))                   # Run again: it drives again
    assert rig.pump_volts == (3.0, 3.0)
    backend.safe_state()
    backend.close()


def test_a_stop_in_the_middle_of_a_request_is_a_silence_too(device: Callable[..., Any]) -> None:
    """Stopped between sending a request and reading its answer (test_guard's
    SIGSTOP under load): the device heard nothing for 1.3 s and its watchdog fired,
    but the silence was measured from the answer and the run drove on."""
    clock, rig, backend, _ = _rig_and_backend(device)
    backend.arm(0.1)
    backend.write_pumps((0.3, 0.3))
    read = rig.read

    def stopped_meanwhile(address: int, count: int) -> list[int]:
        words = read(address, count)
        clock.now += 1.3                              # the answer read 1.3 s later
        return words

    rig.read = stopped_meanwhile  # type: ignore[method-assign]
    backend.read_levels()
    rig.read = read  # type: ignore[method-assign]
    with pytest.raises(BackendError, match=r"^no request reached the rig for 1\.3 s, longer than the watchdog "
                       r"timeout 1 s"):
        backend.write_pumps((0.3, 0.3))
    backend.safe_state()
    backend.close()


def test_the_guard_of_a_dead_program_stops_the_pumps_and_disarms_the_watchdog(device: Callable[..., Any]) -> None:
    """The guard's work, in process: the program it watches is gone without a
    'bye'; it writes each pump's stop value and then disarms the watchdog the
    program had armed (a next program would find its pumps stopped after each
    silence), and says so."""
    import io
    import json
    import os
    import subprocess
    from dataclasses import asdict

    from quadtank_tui.daq.guard import GuardSpec, guard_main

    clock, rig, backend, _ = _rig_and_backend(device)
    backend.arm(0.1)
    backend.write_pumps((0.3, 0.4))
    assert rig.watchdog is not None and rig.watchdog.enabled and rig.pump_volts == (3.0, 4.0)
    dead = subprocess.Popen(["true"])
    dead.wait()
    c = backend.config
    spec = GuardSpec(dead.pid, c.host, c.port, c.device_id, c.timeout,
                     [("DAC0", 1000, [0, 0]), ("DAC1", 1002, [0, 0])], 1.0,
                     disarm=[("watchdog enable", 61600, [0, 0])])
    r, w = os.pipe()
    os.write(w, json.dumps(asdict(spec)).encode() + b"\n")
    os.close(w)
    said = io.StringIO()
    with os.fdopen(r, "rb") as pipe:
        assert guard_main(pipe, said) == 0
    assert rig.pump_volts == (0.0, 0.0) and not rig.watchdog.enabled
    assert said.getvalue().endswith(
        f"quadtank guard: the program driving the rig (pid {dead.pid}) ended without stopping its pumps (killed, "
        f"or it crashed); pumps (DAC0, DAC1) set to 0 over the guard's own connection to 127.0.0.1:{c.port}; "
        "its watchdog disarmed\n")
    backend.close()


def test_a_new_sampling_time_gives_the_guard_the_new_timeout(
        device: Callable[..., Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """TSamp 0.1 s -> 5 s while driven: the device's watchdog is re-armed with 10 s,
    and so must the guard be - with the old 1 s it zeroed the pumps of a program
    stopped for 4 s, which then drove them again with no fault (review of issue 24)."""
    import quadtank_tui.daq.modbus as modbus

    FakeGuard, started, released = recording_guard()

    monkeypatch.setattr(modbus, "Guard", FakeGuard)
    clock, rig, _, _ = _rig_and_backend(device)
    d = device((0.0,) * 4, bank=rig)
    backend = ModbusBackend(d.config(), clock=clock)
    backend.arm(0.1)
    backend.write_pumps((0.3, 0.3))
    assert [s.gap for s in started] == [1.0] and released == []
    backend.arm(5.0)
    backend.read_levels()
    assert rig.watchdog is not None and rig.watchdog.timeout == 10.0
    assert [s.gap for s in started] == [1.0, 10.0] and released == [1.0]
    assert backend.guard is not None and backend.guard.spec.gap == 10.0
    backend.arm(5.0)                                  # the same timeout: the same guard
    backend.read_levels()
    assert len(started) == 2
    backend.safe_state()
    backend.close()
    assert released == [1.0, 10.0]


def _driven_with_a_guard(device: Callable[..., Any]) -> tuple[ModbusBackend, Any]:
    """A backend driving the pumps at TSamp 0.1 s with a real guard process."""
    clock, rig, _, _ = _rig_and_backend(device)
    backend = ModbusBackend(device((0.0,) * 4, bank=rig).config(), clock=clock)
    backend.arm(0.1)
    backend.write_pumps((0.3, 0.3))
    assert backend.guard is not None
    return backend, backend.guard


@pytest.mark.wallclock
def test_a_dead_guard_ends_active_control_and_run_starts_a_new_one(device: Callable[..., Any],
                                                                    poll: Callable[..., bool]) -> None:
    """The guard killed (its user, the OOM killer) while the program drives on: the
    next sample says so and pauses, instead of driving unguarded - after which a
    SIGKILL of the program left a map with `watchdog: none` at 3 V (review of issue 24)."""
    import os
    import signal

    backend, guard = _driven_with_a_guard(device)
    os.kill(guard.pid, signal.SIGKILL)
    assert poll(lambda: guard.ended() is not None, 10.0)
    with pytest.raises(BackendError, match=r"^the guard process ended \(exit status -9\): nothing would stop "
                       r"the pumps if this program died\. Active control ends here"):
        backend.read_levels()
    backend.safe_state()
    backend.read_levels()                             # the next sample starts a new guard
    assert backend.guard is not None and backend.guard.pid != guard.pid and backend.guard.ended() is None
    backend.close()


@pytest.mark.wallclock
def test_the_guard_ignores_a_quadtank_tui_folder_in_the_current_folder(
        device: Callable[..., Any], tmp_path: Any, monkeypatch: pytest.MonkeyPatch,
        poll: Callable[..., bool]) -> None:
    """`quadtank run --daq` started in a folder holding another `quadtank_tui/` (a
    checkout of another version): the guard imported that one and died at start."""
    (tmp_path / "quadtank_tui").mkdir()
    (tmp_path / "quadtank_tui" / "__init__.py").write_text('raise ImportError("another checkout")\n')
    monkeypatch.chdir(tmp_path)
    backend, guard = _driven_with_a_guard(device)
    assert not poll(lambda: guard._proc.poll() is not None, 2.0), "the guard died at start"
    backend.safe_state()
    backend.close()
