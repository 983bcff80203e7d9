"""Helpers of the DAQ tests that a test module imports (conftest.py holds the fixtures)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

from quadtank_tui.daq.registers import Register, decode, encode
from quadtank_tui.daq.server import IllegalAddress

ROOT = Path(__file__).parents[2]
VIRTUAL_RIG = ROOT / "params" / "virtual-rig.yaml"

#: The answer timeout of a test's link, s, where the timeout is not what the test is
#: about: the shipped maps' 0.2 s is a LabJack's, and a rig subprocess on a loaded
#: 2-core CI machine missed it now and then (a fault nobody meant).  The tests of
#: timeouts name theirs.
LINK_TIMEOUT = 5.0

DAC = Register("holding", 1000, "float32", "big")  # the LabJack map virtual-rig.yaml uses


class FixedBank:
    """The LabJack map (AIN0..AIN3 at 0..7, DAC0/DAC1 at 1000..1003, FLOAT32 big-endian)
    with sensor voltages the test sets: a device that reads what we say."""

    def __init__(self, volts: tuple[float, float, float, float]) -> None:
        self.words: dict[int, int] = dict(zip(range(1000, 1004), encode(DAC, 0.0) * 2))
        self.set_volts(volts)

    def set_volts(self, volts: tuple[float, float, float, float]) -> None:
        for i, v in enumerate(volts):
            for a, w in zip((2 * i, 2 * i + 1), encode(Register("input", 2 * i, "float32", "big"), v)):
                self.words[a] = w

    def read(self, address: int, count: int) -> list[int]:
        if any(a not in self.words for a in range(address, address + count)):
            raise IllegalAddress(address)
        return [self.words[a] for a in range(address, address + count)]

    def write(self, address: int, values: Sequence[int]) -> None:
        if not all(1000 <= a < 1004 for a in range(address, address + len(values))):
            raise IllegalAddress(address)
        self.words.update(zip(range(address, address + len(values)), values))

    def dacs(self) -> tuple[float, float]:
        return (decode(DAC, [self.words[1000], self.words[1001]]),
                decode(DAC, [self.words[1002], self.words[1003]]))


def rig_yaml(port: int, source: Path = VIRTUAL_RIG, timeout: float = LINK_TIMEOUT) -> str:
    """The text of a shipped map (params/virtual-rig.yaml) pointed at `port`, with
    `timeout`: what a test writes as the --daq file of a command."""
    text = source.read_text()
    assert "port: 5020" in text and "timeout: 0.2" in text, source
    return text.replace("port: 5020", f"port: {port}").replace("timeout: 0.2", f"timeout: {timeout:g}")


def missed_slots(log: Path, tsamp: float) -> list[int]:
    """Per row of a log that came late, the sampling slots a busy machine let go by
    before it, in order ('% late: the next row was sampled 0.3 s after the previous
    one, not TSamp 0.1 s': two).  Rows that came on time have no note."""
    missed = []
    for line in log.read_text().splitlines():
        if line.startswith("% late: the next row was sampled "):
            gap = float(line.split("sampled ")[1].split(" s")[0])
            missed.append(round(gap / tsamp) - 1)
    return missed


def missed_before_the_last_row(log: Path, tsamp: float) -> int:
    """The slots that went by just before the log's last row (0: it came on time).  A
    run ends once its duration's slots have passed, so a late last row may carry the
    count of slots past the duration by these."""
    lines = [line for line in log.read_text().splitlines() if line.strip()]
    return missed_slots(log, tsamp)[-1] if len(lines) >= 2 and lines[-2].startswith("% late:") else 0


def recording_guard() -> tuple[type, list[Any], list[float]]:
    """A stand-in for daq.guard.Guard (monkeypatched into daq.modbus) that starts no
    process: the class, the specs it was started with, and the gaps of those released."""
    started: list[Any] = []
    released: list[float] = []

    class FakeGuard:
        def __init__(self, spec: Any) -> None:
            self.spec = spec
            started.append(spec)

        def ended(self) -> int | None:
            return None

        def beat(self) -> None:
            pass

        def release(self, wait: float = 1.0) -> None:
            released.append(self.spec.gap)

    return FakeGuard, started, released


def simul_twin(active_log: Path, start: Callable[[Any], None], duration: float, tmp_path: Path,
               par: Path | None = None) -> dict[str, Any]:
    """The columns of the Simul run of an Active run's experiment (`start` issues it),
    from the levels the rig had at the active log's first row, as a user fills the
    tanks; the two logs' slots are checked to be the same."""
    import numpy as np

    from quadtank_tui.engine.commands import AddWater, LogSave
    from quadtank_tui.engine.runner import build_engine
    from quadtank_tui.files.log_reader import read_log

    a = read_log(active_log).columns()
    simul = build_engine(par, clock="manual", params_dir=ROOT / "params", logs_dir=tmp_path)
    try:
        y_sim = simul.snapshot().y
        for tank in range(4):
            assert simul.submit(AddWater(tank + 1, float(a[f"y{tank + 1}"][0]) - y_sim[tank])).result().ok
        start(simul)
        simul.run_for(duration)
        assert simul.submit(LogSave("simul")).result().ok
    finally:
        simul.stop()
    s = read_log(tmp_path / "simul.log").columns()
    assert len(s["y1"]) == len(a["y1"])
    np.testing.assert_allclose(a["t"], s["t"], atol=1e-9)  # the same slots, every one
    return s


def ok(engine: Any, command: object) -> None:
    """`command` submitted to `engine`, and accepted."""
    result = engine.submit(command).result()
    assert result.ok, result.message


def start_experiment(engine: Any, experiment: dict[str, Any]) -> None:
    """The same sequence a user does on the Main screen: Automatic, the experiment's
    settings (references on), LogOn, Run."""
    from quadtank_tui.engine.commands import LogOn, SetControlMode, SetParams, SetState

    ok(engine, SetControlMode("Automatic"))
    ok(engine, SetParams(experiment))
    ok(engine, LogOn())
    ok(engine, SetState("Run"))


def active_run(engine: Any, backend: str, start: Callable[[Any], None], duration: float) -> None:
    """The experiment `start` issues, in Active on `engine` (its backend described
    as `backend`) for `duration` process seconds without a fault, saved as
    active.log; the engine stopped (pumps to 0) in any case."""
    from quadtank_tui.engine.commands import LogSave, SetOperation

    try:
        ok(engine, SetOperation("Active"))
        first = engine.step()          # a paused Active loop shows the rig's levels
        assert first.operation == "Active" and first.backend == backend
        start(engine)
        engine.run_for(duration)
        snap = engine.snapshot()
        assert snap.fault is None and snap.state == "Run" and snap.alarms == ()
        ok(engine, LogSave("active"))
    finally:
        engine.stop()
