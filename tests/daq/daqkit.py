"""Helpers of the DAQ tests that a test module imports (conftest.py holds the fixtures)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

ROOT = Path(__file__).parents[2]
VIRTUAL_RIG = ROOT / "params" / "virtual-rig.yaml"

#: The answer timeout of a test's link, s, where the timeout is not what the test is
#: about: the shipped maps' 0.2 s is a LabJack's, and a rig subprocess on a loaded
#: 2-core CI machine missed it now and then (a fault nobody meant).  The tests of
#: timeouts name theirs.
LINK_TIMEOUT = 5.0


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
