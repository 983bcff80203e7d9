"""Helpers of the DAQ tests that a test module imports (conftest.py holds the fixtures)."""

from __future__ import annotations

from pathlib import Path

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
