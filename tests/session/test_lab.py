"""The lab configuration file: values, defaults, and refusals that name the file,
the line and the key."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from quadtank_tui.session import lab as labmod
from quadtank_tui.session.folders import RuntimeFolderError
from quadtank_tui.session.lab import (
    LabConfig, LabConfigError, ensure_runtime_dir, load_lab_config, parse_lab_config,
)
from quadtank_tui.session.policy import UnattendedPolicy

FULL = """\
# the lab of room M:2112
admin_group: teachers
share_group: lab
runtime_dir: /run/quadtank
defaults: /opt/quadtank/params
unattended:
  keep_while_logging: false
  grace_minutes: 2.5
"""


@pytest.fixture(autouse=True)
def _no_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv("QUADTANK_LAB", raising=False)
    monkeypatch.delenv("QUADTANK_RUNTIME", raising=False)
    monkeypatch.setattr(labmod, "SYSTEM_LAB_FILE", tmp_path / "no-such-lab.yaml")


ROOT = Path(__file__).resolve().parents[2]


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "lab.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_full_file(tmp_path: Path) -> None:
    path = write(tmp_path, FULL)
    assert load_lab_config(path) == LabConfig(
        admin_group="teachers", runtime_dir=Path("/run/quadtank"), share_group="lab",
        unattended=UnattendedPolicy(keep_while_logging=False, grace_minutes=2.5), source=path,
        params_dir=Path("/opt/quadtank/params"), runtime_source="lab file")


def test_no_file_gives_the_defaults() -> None:
    assert load_lab_config() == LabConfig(None, Path("/tmp/quadtank-sessions"), None, UnattendedPolicy(), None,
                                          ROOT / "params", runtime_source="default")  # the installation's, not ./params


def test_empty_file_and_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write(tmp_path, "# nothing set yet\n")
    monkeypatch.setenv("QUADTANK_LAB", str(path))
    monkeypatch.setenv("QUADTANK_RUNTIME", str(tmp_path / "rt"))
    got = load_lab_config()
    assert (got.source, got.runtime_dir, got.admin_group, got.unattended) == (
        path, tmp_path / "rt", None, UnattendedPolicy())


def test_relative_folders_are_taken_from_the_file(tmp_path: Path) -> None:
    got = load_lab_config(write(tmp_path, "runtime_dir: run\ndefaults: ../params\n"))
    assert got.runtime_dir == tmp_path / "run"
    assert got.params_dir == tmp_path / "../params"


def test_named_file_must_exist(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("QUADTANK_LAB", str(tmp_path / "missing.yaml"))
    with pytest.raises(LabConfigError, match=r"missing\.yaml: no such file"):
        load_lab_config()


@pytest.mark.parametrize("text,where", [
    ("admin_group: teachers\nadmin_grup: x\n", "lab.yaml:2: admin_grup: unknown key; expected one of "
     "admin_group, share_group, runtime_dir, defaults, unattended"),
    ("unattended:\n  keep_while_logging: yes\n  grace: 3\n", "lab.yaml:3: unattended.grace: unknown key"),
    ("unattended:\n  keep_while_logging: 1\n", "lab.yaml:2: unattended.keep_while_logging: must be true or false, got 1"),
    ("unattended:\n  grace_minutes: -1\n", "lab.yaml:2: unattended.grace_minutes: must be a number of minutes 0..1440, got -1"),
    ("unattended:\n  grace_minutes: ten\n", "lab.yaml:2: unattended.grace_minutes: must be a number"),
    ("unattended: 10\n", "lab.yaml:1: unattended: must be a mapping"),
    ("\n\nadmin_group: [a, b]\n", "lab.yaml:3: admin_group: must be the name of an operating-system group"),
    ("share_group: 'two words'\n", "lab.yaml:1: share_group: must be the name"),
    ("runtime_dir: 5\n", "lab.yaml:1: runtime_dir: must be a folder path, got 5"),
    ("- admin_group\n", "lab.yaml:1: must be a mapping of keys"),
    ("admin_group: [\n", "lab.yaml:2: not valid YAML"),
])
def test_bad_files_name_file_line_key(tmp_path: Path, text: str, where: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(LabConfigError) as caught:
        load_lab_config(path)
    assert str(caught.value).startswith(str(tmp_path / where))


def test_alias_bomb_and_size_are_bounded(tmp_path: Path) -> None:
    bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 10)}]\n" for i in range(6))
    with pytest.raises(LabConfigError, match="aliases"):
        load_lab_config(write(tmp_path, bomb))
    big = tmp_path / "big.yaml"
    big.write_bytes(b"#" * 1_000_001)
    with pytest.raises(LabConfigError, match="larger than"):
        load_lab_config(big)


def test_parse_without_a_file() -> None:
    assert parse_lab_config("admin_group: staff\n").admin_group == "staff"


def test_a_runtime_dir_named_and_missing_is_made_ours(tmp_path: Path) -> None:
    """Named ($QUADTANK_RUNTIME, a program) and missing: made by its user; root's
    (an administrator's) is a lab folder (1755, users/ and locks/ 1777 sticky),
    anyone else's their own (0755 throughout), which no other user trusts."""
    lab = LabConfig(runtime_dir=tmp_path / "deep" / "rt")
    root = ensure_runtime_dir(lab)
    assert root.path == tmp_path / "deep" / "rt" and root.lab is (os.getuid() == 0)
    modes = (0o1755, 0o1777) if os.getuid() == 0 else (0o755, 0o755)
    assert stat.S_IMODE(os.stat(root.path).st_mode) == modes[0]
    assert stat.S_IMODE(os.stat(root.users).st_mode) == stat.S_IMODE(os.stat(root.locks).st_mode) == modes[1]
    os.chmod(root.path, 0o1777)  # an older version's folder of ours
    assert ensure_runtime_dir(lab) == root  # a second time: made ours alone again
    assert stat.S_IMODE(os.stat(root.path).st_mode) == modes[0]


def test_a_planted_link_is_not_a_runtime_dir(tmp_path: Path) -> None:
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "rt").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(RuntimeFolderError, match="not a folder"):
        ensure_runtime_dir(LabConfig(runtime_dir=tmp_path / "rt"))
