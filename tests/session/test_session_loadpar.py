"""A session reads a LoadPar's file on a thread of its own: its one driver thread
keeps sampling and publishing while the file hangs (a slow NFS home: here a
monkeypatched ParStore.load); the operator's later commands are answered after
it, in order; a bad file is refused with the message the loop gives."""

from __future__ import annotations

import shutil
import threading
from pathlib import Path
from typing import Any, Callable

import pytest
from sessionkit import ThreadSession

from quadtank_tui.engine import commands as c
from quadtank_tui.session.client import SessionClient

K = "CONTROLLER ONE.K"



def test_the_session_samples_while_a_par_file_hangs(thread_session, monkeypatch: pytest.MonkeyPatch,
                                                    poll: Callable[..., bool]) -> None:
    s: ThreadSession = thread_session(speed=100.0)
    client = SessionClient(s.path)
    try:
        assert client.submit(c.SetParams({K: 2.5})).result(10).ok
        assert client.submit(c.SavePar("mine", overwrite=True)).result(10).ok
        assert client.submit(c.SetParams({K: 1.0})).result(10).ok
        gate, reading = threading.Event(), threading.Event()
        store = s.engine.par_store
        real = store.load

        def load(name: str, *args: Any, **kw: Any) -> Any:
            reading.set()
            assert gate.wait(30.0)
            return real(name, *args, **kw)

        monkeypatch.setattr(store, "load", load)
        loading = client.submit(c.LoadPar("mine"))
        after = client.submit(c.SetParams({K: 7.0}))
        assert reading.wait(10.0)
        n0 = s.engine.snapshot().stats.samples
        assert poll(lambda: s.engine.snapshot().stats.samples >= n0 + 50, 20.0), "the session stopped sampling"
        assert poll(lambda: client.snapshot().stats.samples >= n0 + 20, 20.0), "the client got no updates"
        assert not loading.done() and not after.done()
        gate.set()
        assert loading.result(10).message == "loaded mine"
        assert after.result(10).ok
        assert s.engine.snapshot().params.get(K) == 7.0
        (Path(store.folder) / "bad.par").write_text("% TANK PAR-file\n\nSAMPLING TIME\nTSamp fast\n")
        said = client.submit(c.LoadPar("bad")).result(10)
        assert not said.ok and said.message.startswith(f"{Path(store.folder) / 'bad.par'}, line 4: ")
        assert s.engine.snapshot().params.get(K) == 7.0
    finally:
        client.close()


def test_a_session_loading_in_automatic_keeps_the_references(thread_session) -> None:
    """The session reads the file off its driver's thread and installs it between
    samples (InstallPar): the bumpless rule of tests/engine/test_par_load_bumpless.py
    holds there too - the references in force stay, the rest of the file applies."""
    s: ThreadSession = thread_session(speed=200.0)
    (s.runtime.parent / "params").mkdir(exist_ok=True)
    shutil.copy(Path(__file__).parents[2] / "params" / "nonminphase.par", s.runtime.parent / "params")
    means = ("REFERENCE ONE.Mean", "REFERENCE TWO.Mean")
    with SessionClient(s.path) as client:
        assert client.submit(c.SetControlMode("Automatic")).result(10).ok
        r0 = tuple(s.engine.snapshot().params.get(m) for m in means)
        assert client.submit(c.SetState("Run")).result(10).ok
        said = client.submit(c.LoadPar("nonminphase")).result(10)
        assert said.ok and "references kept" in said.message, said.message
    p = s.engine.snapshot().params
    assert tuple(p.get(m) for m in means) == pytest.approx(r0)
    assert p.get("CONTROLLER ONE.Ti") == 110.0
