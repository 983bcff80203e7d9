"""docs/mpc.md shows what `quadtank mpc` prints: each block that starts with a
`$ quadtank mpc ...` line is the command's output from its comparison on, run
here; every figure but the solve times (p50, p99 ms: the machine's) must match."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from quadtank_tui.cli import main

ROOT = Path(__file__).resolve().parents[2]
BLOCK = re.compile(r"```\n\$ (quadtank mpc [^\n]*)\n\.\.\.\n(.*?)\n```", re.S)


def _without_times(text: str) -> list[str]:
    """The lines, the MPC row's last two columns (solve times) dropped."""
    out = []
    for line in text.strip().splitlines():
        if line.startswith("MPC "):
            line = " ".join(line.split()[:-2])
        out.append(line.rstrip())
    return out


def _blocks() -> list[tuple[str, str]]:
    return BLOCK.findall((ROOT / "docs" / "mpc.md").read_text(encoding="utf-8"))


def test_the_doc_has_the_p_minus_and_p_plus_comparisons() -> None:
    commands = [c for c, _ in _blocks()]
    assert any("minphase.par" in c and "nonminphase" not in c for c in commands)
    assert any("nonminphase.par" in c for c in commands)


@pytest.mark.parametrize("command, shown", [pytest.param(c, b, id=Path(shlex.split(c)[3]).stem) for c, b in _blocks()])
def test_mpc_doc_block_is_what_the_command_prints(command: str, shown: str, capsys, monkeypatch) -> None:
    monkeypatch.chdir(ROOT)
    assert main(shlex.split(command)[1:]) == 0
    printed = capsys.readouterr().out
    printed = printed[printed.index("nonlinear simulation"):]
    assert _without_times(printed) == _without_times(shown)
