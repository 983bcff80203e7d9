"""`quadtank --daq C` while your own session drives that rig attaches to it (saying
so), as plain `quadtank` does, instead of refusing you your own rig; another
user's session on it is refused as before, naming the holder and since when.

A real session process started by `quadtank --daq C` (the TUI replaced by a
stand-in that detaches at once); no rig needs to answer: the session starts in
Simul."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any, Callable

import pytest

from quadtank_tui.cli import main
from quadtank_tui.commands import sessions as sessions_command
from quadtank_tui.session.client import stop_session_at
from quadtank_tui.session.lab import load_lab_config
from quadtank_tui.session import lock as lockmod
from quadtank_tui.session.lock import holder_of, lock_path
from quadtank_tui.files.proc import pid_alive
from quadtank_tui.session.runtime import list_sessions

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc")

ROOT = Path(__file__).parents[2]


def test_your_own_session_on_the_rig_is_attached_to(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str],
                                                    poll: Callable[..., bool], unused_port: int) -> None:
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.delenv("QUADTANK_LAB", raising=False)
    monkeypatch.chdir(tmp_path)
    port = unused_port  # bound, never listening: no rig answers, none of another test
    text = (ROOT / "params" / "virtual-rig.yaml").read_text().replace("port: 5020", f"port: {port}")
    cfg, named = tmp_path / "rig.yaml", tmp_path / "rig-by-name.yaml"
    cfg.write_text(text)
    named.write_text(text.replace("host: 127.0.0.1", "host: LOCALHOST"))  # the same rig, by name
    attached: list[str] = []

    def tui(client: Any, refresh: float) -> int:  # the TUI, detaching at once
        attached.append(client.info.id)
        client.close()
        return 0

    monkeypatch.setattr(sessions_command, "run_tui_on", tui)
    assert main(["--daq", str(cfg)]) == 0  # starts the session, which takes the rig
    (info,) = list_sessions(runtime)
    device = f"127.0.0.1:{port}/1"
    try:
        held = holder_of(device, load_lab_config())
        assert held is not None and (held.pid, held.session) == (info.pid, info.id)
        capsys.readouterr()
        for config in (cfg, named):
            assert main(["--daq", str(config)]) == 0
            assert capsys.readouterr().err.startswith(
                f"quadtank: the rig at {device} is driven by your session {info.id}: attaching to it\n")
        assert attached == [info.id] * 3 and len(list_sessions(runtime)) == 1
        # --no-session drives the rig from this terminal: still refused
        assert main(["--no-session", "--daq", str(cfg)]) == 2
        assert f"is driven by {info.owner} (pid {info.pid}, session {info.id})" in capsys.readouterr().err

        # Another user's session on the rig (its record names another uid, in a file of
        # that user, about a process of that user): refused as before.
        if os.getuid() != 0:
            return  # a record of another user needs root to write (chown); a forged one is free
        record = json.loads(lock_path(device, load_lab_config()).read_text())
        path = lock_path(device, load_lab_config(), os.getuid() + 1)  # beside the session's own record,
        path.write_text(json.dumps({**record, "uid": os.getuid() + 1}))  # which is no longer genuine here
        os.chown(path, os.getuid() + 1, -1)
        owner = lockmod.process_owner
        monkeypatch.setattr(lockmod, "process_owner", lambda pid: os.getuid() + 1 if pid == info.pid else owner(pid))
        assert main(["--daq", str(named)]) == 2
        since = held.since.strftime("%H:%M")
        assert capsys.readouterr().err == (
            f"quadtank: error: the rig at LOCALHOST:{port}/1 (127.0.0.1:{port}/1) is driven by {info.owner} "
            f"(pid {info.pid}, session {info.id}) since {since}; ask them to stop it, or an administrator may "
            "take it over (--take-over)\n")
        assert attached == [info.id] * 3
    finally:
        stop_session_at(info.socket)
    assert poll(lambda: not pid_alive(info.pid), 5.0)
    assert holder_of(device, load_lab_config()) is None  # the session gave the rig back
