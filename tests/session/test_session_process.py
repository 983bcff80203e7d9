"""Real session processes: what is promised about processes holds for processes.

- The session process SIGKILLed: an attached client says so within a second and
  refuses commands; listing the sessions marks its stale record ended, saying so.
- `quadtank stop SESSION` leaves no process, socket or shared-memory file; its
  record and output say why it ended, and `quadtank sessions` lists it.
- `quadtank` in a pseudo-terminal that hangs up (directly, and under a shell that
  keeps SIGHUP as `make run` does): the TUI is gone within a second or so, the
  session runs on, and a new `quadtank` attaches to it with its whole history.
"""

from __future__ import annotations

import os
import re
import signal
import stat
import sys
import time
from pathlib import Path
from typing import Any, Callable

import pytest
from sessionkit import place, place_files

from quadtank_tui.cli import main
from quadtank_tui.engine import commands as c
from quadtank_tui.engine.runner import engine_spec
from quadtank_tui.session.client import SessionClient
from quadtank_tui.session.launch import SessionSpec, start_session
from quadtank_tui.files.proc import pid_alive
from quadtank_tui.session.runtime import ended_sessions, list_sessions, socket_path

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and Linux ptys")

ROOT = Path(__file__).parents[2]


def _stop_for_good(pid: int, poll: Callable[..., bool]) -> None:
    """SIGTERM, then SIGKILL if it is still there: a session a failed test leaves
    (one that no longer heeds SIGTERM, say) must not run on, sampling, through the
    rest of the suite."""
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    if not poll(lambda: not pid_alive(pid), 10.0):
        os.kill(pid, signal.SIGKILL)


def _start(tmp_path: Path, runtime: Path, **kwargs: object):
    spec = engine_spec(clock="virtual", speed=100.0, params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    return start_session(SessionSpec(spec, str(runtime), **kwargs))  # type: ignore[arg-type]


def test_a_killed_session_is_reported_by_its_client(tmp_path: Path, poll: Callable[..., bool]) -> None:
    runtime = tmp_path / "run"
    info = _start(tmp_path, runtime)
    client = SessionClient(info.socket)
    try:
        assert client.submit(c.SetState("Run")).result(30).ok
        time.sleep(0.2)
        t0 = time.monotonic()
        os.kill(info.pid, signal.SIGKILL)
        assert client.wait_gone(30.0)
        took = time.monotonic() - t0
        fault = client.snapshot().fault or ""
        assert f"the session process {info.id} (pid {info.pid}) stopped unexpectedly" in fault
        assert client.snapshot().state == "Pause"
        refused = client.submit(c.SetState("Run")).result(30)
        assert not refused.ok and "gone" in refused.message
        print(f"the client saw the SIGKILL after {took * 1000:.0f} ms")
    finally:
        client.close()
    poll(lambda: not pid_alive(info.pid), 60.0)
    assert list_sessions(runtime) == []  # the stale record is no running session ...
    (ended,) = ended_sessions(runtime)   # ... but an ended one that says so
    assert ended.id == info.id and f"the session process (pid {info.pid}) was gone without stopping" in ended.ended
    assert [n for n in place_files(runtime) if not n.endswith(".out")] == [f"{info.id}.json"]


def test_quadtank_stop_leaves_no_process_nor_socket_and_says_why(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture[str], poll: Callable[..., bool]) -> None:
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    info = _start(tmp_path, runtime)
    # Any local user may reach the socket and the session decides who is let in (a
    # mode naming one group shut out a teacher outside it; tried with real users).
    assert stat.S_IMODE(os.stat(info.socket).st_mode) == 0o666
    with SessionClient(info.socket) as client:
        assert client.submit(c.SetState("Run")).result(30).ok
        assert client.submit(c.LogOn(points=100000)).result(30).ok
        assert poll(lambda: client.snapshot().log.rows >= 20, 60.0)
    deadline = time.monotonic() + 60
    while main(["sessions"]) == 0 and "1 (" in (table := capsys.readouterr().out) and time.monotonic() < deadline:
        time.sleep(0.05)  # the record follows the detach at once; wait for the session to see it
    assert info.id in table and "Run" in table and "%" in table and f"({info.owner} operates)" not in table
    assert main(["stop", info.id]) == 0
    out = capsys.readouterr().out
    assert f"session {info.id} stopped (stopped by " in out
    assert not pid_alive(info.pid)
    # No socket; the record and the output say why it ended, and `sessions` lists it.
    assert place_files(runtime) == [f"{info.id}.json", f"{info.id}.out"]
    assert f"session {info.id} stopped: stopped by {info.owner}" in (place(runtime) / f"{info.id}.out").read_text()
    assert main(["sessions"]) == 0
    listed = capsys.readouterr().out
    assert listed.startswith("no running sessions\n\nended (kept 7 days")
    assert re.search(rf"^{info.id} +{info.owner} .* stopped by {info.owner}$", listed, re.M), listed
    partial = list((tmp_path / "logs").glob("*.partial"))
    assert partial, "the unsaved log is kept"
    assert main(["stop", info.id]) == 2  # nothing left to stop: one line, status 2


def test_a_bad_session_start_says_why(tmp_path: Path) -> None:
    from quadtank_tui.session.launch import SessionStartError

    with pytest.raises(SessionStartError, match="no-such.yaml"):
        _start(tmp_path, tmp_path / "run", daq_config=str(tmp_path / "no-such.yaml"))
    assert list_sessions(tmp_path / "run") == []


@pytest.mark.parametrize("shell", [False, True], ids=["direct", "under a shell that keeps SIGHUP (make run)"])
def test_a_hang_up_ends_the_client_never_the_session(tmp_path: Path, shell: bool, pty_kit: Any, poll: Callable[..., bool]) -> None:
    kit = pty_kit
    runtime = tmp_path / "run"
    env = {"QUADTANK_RUNTIME": str(runtime)}
    tui = kit.Tui(tmp_path, shell=shell, args=("--speed", "50"), env=env)
    try:
        pid, session = tui.started_session(runtime)
        os.write(tui.master, b"r")  # Run
        assert poll(lambda: [i.state for i in list_sessions(runtime)] == ["Run"], 60.0)
        tui.hang_up()
        took = kit._wait_gone([pid], kit.GONE_WITHIN)
        print(f"hang-up ({'shell' if shell else 'direct'}): the client was gone {took:.2f} s after")
        assert took < kit.GONE_WITHIN
        assert pid_alive(session.pid)  # the session runs on
        time.sleep(0.3)
        with SessionClient(session.socket, role="observer") as watcher:
            snap = watcher.snapshot()
            assert snap.state == "Run" and snap.k > 0
            assert len(watcher.history()["t"]) == snap.k  # nothing missed
    finally:
        tui.kill()
        for info in list_sessions(runtime):
            _stop_for_good(info.pid, poll)


def test_a_second_session_on_the_same_daq_is_refused_with_the_holders_name(tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """The session process holds the rig's lock (the link itself opens on the first
    Active sample: no rig needs to run here); a second one is refused, naming the
    holder; once the first stops, the rig is free."""
    from quadtank_tui.session.client import stop_session_at
    from quadtank_tui.session.launch import SessionStartError

    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    config = str(ROOT / "params" / "virtual-rig.yaml")
    first = _start(tmp_path, runtime, daq_config=config)
    try:
        with pytest.raises(SessionStartError, match=rf"the rig at 127\.0\.0\.1:5020/\d+ is driven by "
                           rf"{first.owner} \(pid {first.pid}, session {first.id}\) since \d\d:\d\d"):
            _start(tmp_path, runtime, daq_config=config)
        assert [i.id for i in list_sessions(runtime)] == [first.id]
    finally:
        stop_session_at(first.socket)
    second = _start(tmp_path, runtime, daq_config=config)
    stop_session_at(second.socket)


def test_run_detach_is_a_session_one_watches_until_the_run_is_over(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                   capsys: pytest.CaptureFixture[str], poll: Callable[..., bool]) -> None:
    """`quadtank run ... --detach` returns at once; a client attaching to the session
    watches it read-only (the script is the operator); at the end the log has every
    sample of the duration and the session is gone, leaving only its summary."""
    from quadtank_tui.files.log_reader import read_log

    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "logs" / "detached.log"
    out.parent.mkdir()  # --log's folder must exist (issue 41)
    assert main(["run", "--duration", "200", "--log", str(out), "--speed", "100", "--seed", "3", "--detach"]) == 0
    said = capsys.readouterr().out
    (info,) = list_sessions(runtime)
    assert f"session {info.id} runs the experiment" in said and info.headless
    with SessionClient(info.socket) as watcher:  # asked to operate: observes
        assert watcher.role == "observer" and "the script" in watcher.controller
        refused = watcher.submit(c.SetState("Pause")).result(30)
        assert not refused.ok and "read-only" in refused.message
        assert watcher.wait_gone(30)
        assert watcher.ended is not None and f"the run is over; its log is {out}" in watcher.ended
        assert len(watcher.history()["t"]) == 2000  # every sample, watched from wherever it was at attach
    log = read_log(out)
    assert log.rows == 2000
    poll(lambda: not pid_alive(info.pid), 60.0)
    assert place_files(runtime) == [f"{info.id}.json", f"{info.id}.out"]
    assert f"log        {out} (2000 rows)" in (place(runtime) / f"{info.id}.out").read_text()
    (ended,) = ended_sessions(runtime)
    assert ended.ended == f"the run is over; its log is {out}"


def test_sigterm_stops_the_session_in_order(tmp_path: Path, poll: Callable[..., bool]) -> None:
    """SIGTERM (a shutdown, `kill`): the session stops as `quadtank stop` does - the
    clients are told why, the log is kept, nothing is left in the runtime folder."""
    runtime = tmp_path / "run"
    info = _start(tmp_path, runtime)
    try:
        with SessionClient(info.socket) as client:
            assert client.submit(c.SetState("Run")).result(30).ok
            assert client.submit(c.LogOn(points=100000)).result(30).ok
            time.sleep(0.3)
            os.kill(info.pid, signal.SIGTERM)
            assert client.wait_gone(30)
            assert client.ended == "SIGTERM"
            assert "ended: SIGTERM" in (client.snapshot().fault or "")
        poll(lambda: not pid_alive(info.pid), 60.0)
    finally:
        if pid_alive(info.pid):  # the test failed: the session must not outlive it
            os.kill(info.pid, signal.SIGKILL)
    assert not pid_alive(info.pid)
    (ended,) = ended_sessions(runtime)
    assert ended.ended == "SIGTERM" and not socket_path(place(runtime), info.id).exists()
    assert "stopped: SIGTERM" in (place(runtime) / f"{info.id}.out").read_text()
    assert list((tmp_path / "logs").glob("*.partial"))


def test_a_session_launched_with_its_stop_signals_blocked_still_stops_on_sigterm(tmp_path: Path, poll: Callable[..., bool]) -> None:
    """A process inherits its launcher's signal mask: a session spawned while they
    were blocked (a pytest whose main thread an interrupted IST write had left with
    every signal blocked) ignored SIGTERM and sat on, sampling, until SIGKILL."""
    runtime = tmp_path / "run"
    stops = {signal.SIGTERM, signal.SIGHUP, signal.SIGINT}
    held = signal.pthread_sigmask(signal.SIG_BLOCK, stops)
    try:
        info = _start(tmp_path, runtime)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
    try:
        os.kill(info.pid, signal.SIGTERM)
        assert poll(lambda: not pid_alive(info.pid), 30)
    finally:
        if pid_alive(info.pid):
            os.kill(info.pid, signal.SIGKILL)
    (ended,) = ended_sessions(runtime)
    assert ended.ended == "SIGTERM"


def test_the_launchers_rig_lock_passes_to_the_session(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str], poll: Callable[..., bool]) -> None:
    """`quadtank run --daq C --detach`: the command takes the rig's lock as every
    rig command does, then hands it to the session process (transfer), which holds
    it until it stops; meanwhile a second command on the rig is refused, naming the
    session."""
    from quadtank_tui.session.client import stop_session_at
    from quadtank_tui.session.lab import load_lab_config
    from quadtank_tui.session.lock import device_key, holder_of

    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.chdir(tmp_path)
    config = str(ROOT / "params" / "virtual-rig.yaml")
    (tmp_path / "logs").mkdir(exist_ok=True)  # --log's folder must exist (issue 41)
    run = ["run", "--duration", "600", "--log", str(tmp_path / "logs" / "rig.log"), "--daq", config, "--detach"]
    assert main(run) == 0
    (info,) = list_sessions(runtime)
    device = device_key("127.0.0.1", 5020, 1)
    try:
        held = holder_of(device, load_lab_config())
        assert held is not None and held.pid == info.pid and held.session == info.id
        capsys.readouterr()
        assert main(run) == 2
        err = capsys.readouterr().err
        assert f"is driven by {info.owner} (pid {info.pid}, session {info.id})" in err
    finally:
        stop_session_at(info.socket)
    poll(lambda: not pid_alive(info.pid), 60.0)
    assert holder_of(device, load_lab_config()) is None


def test_run_detach_refuses_a_script_the_run_would_refuse_before_detaching(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """A script that sets the sampling time while logging: `--detach` says so in the
    terminal with exit 2, as the run without --detach does, and starts no session
    (it said "runs the experiment", exit 0, and the session ended unseen)."""
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.chdir(tmp_path)
    script = tmp_path / "tsamp.yaml"
    script.write_text('- at: 1\n  log: "on"\n- at: 2\n  set: {"SAMPLING TIME.TSamp": 200}\n')
    (tmp_path / "logs").mkdir(exist_ok=True)  # --log's folder must exist (issue 41)
    run = ["run", "--script", str(script), "--duration", "60", "--log", str(tmp_path / "logs" / "t.log")]
    assert main(run) == 2
    undetached = capsys.readouterr().err.splitlines()[-1]
    assert main([*run, "--detach"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == undetached
    assert undetached.startswith(f"quadtank: error: {script}, event 2 (line 3): SAMPLING TIME.TSamp: stop logging")
    assert place_files(runtime) == []
