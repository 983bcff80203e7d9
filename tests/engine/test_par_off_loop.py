"""LoadPar reads the `.par` off the loop's thread (engine/parload.py): a read that
blocks (a slow NFS home, here a monkeypatched ParStore.load waiting on an event)
does not stop the samples; the commands sent after the LoadPar wait behind it, in
order; a bad file gives the message it always gave (file:line and why)."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any, Callable

import pytest

from quadtank_tui.engine.commands import LoadPar, SavePar, SetParams
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.par import ParStore

K = "CONTROLLER ONE.K"



def blocking_reads(monkeypatch: pytest.MonkeyPatch, store: ParStore) -> tuple[threading.Event, list[str]]:
    """store.load waits for the returned event (a file server that hangs); the list
    collects the threads it ran on."""
    gate, threads = threading.Event(), []
    real = store.load

    def load(name: str, *args: Any, **kw: Any) -> Any:
        threads.append(threading.current_thread().name)
        assert gate.wait(30.0)
        return real(name, *args, **kw)

    monkeypatch.setattr(store, "load", load)
    return gate, threads


def engine_with_a_par(tmp_path: Path) -> Engine:
    e = build_engine(clock="virtual", speed=50.0, params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    assert e.submit(SetParams({K: 2.5})).result().ok
    assert e.submit(SavePar("mine", overwrite=True)).result().ok
    assert e.submit(SetParams({K: 1.0})).result().ok
    return e


def test_a_blocked_read_does_not_delay_the_samples(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   poll: Callable[..., bool]) -> None:
    e = engine_with_a_par(tmp_path)
    gate, threads = blocking_reads(monkeypatch, e.loop.store)
    e.start()
    try:
        loading = e.submit(LoadPar("mine"))
        after = e.submit(SetParams({K: 7.0}))          # sent after it: applied after it
        assert poll(lambda: bool(threads), 20.0)
        n0 = e.snapshot().stats.samples
        # 50 sampling periods (5 s of process time at x50: 0.1 s of wall time) while the file hangs
        assert poll(lambda: e.snapshot().stats.samples >= n0 + 50, 20.0), "the loop stopped sampling during the read"
        assert not loading.done() and not after.done()
        assert e.snapshot().params.get(K) == 1.0
        gate.set()
        loaded = loading.result(10)
        assert (loaded.ok, loaded.message) == (True, "loaded mine")
        assert loaded.warnings == (f"{tmp_path / 'params' / 'default.par'} not found: using the built-in "
                                   "(preset) values",)
        assert after.result(10).ok
        assert e.snapshot().params.get(K) == 7.0       # in order: the load, then the SetParams
        assert e.loop.matrix.pid_params(1, 1).K == 7.0
    finally:
        gate.set()
        e.stop()
    assert threads == ["quadtank-par-read"]             # not the loop's thread, not the caller's


BAD = "% TANK PAR-file\n\nSAMPLING TIME\nTSamp fast\n"


@pytest.mark.parametrize("name", ["bad", "missing"])
def test_a_bad_file_gives_the_same_message(name: str, tmp_path: Path) -> None:
    """The message of the inline path (a manual engine reads on the spot) is the
    running engine's, word for word; the parameters in force stay."""
    inline = engine_with_a_par(tmp_path)
    (tmp_path / "params" / "bad.par").write_text(BAD)
    said = inline.submit(LoadPar(name)).result()
    assert not said.ok
    assert said.message.startswith(str(tmp_path / "params" / f"{name}.par"))
    if name == "bad":
        assert "line 4" in said.message and "fast" in said.message, said.message
    running = engine_with_a_par(tmp_path)
    running.start()
    try:
        assert running.submit(LoadPar(name)).result(10) == said
        assert running.snapshot().params.get(K) == 1.0
    finally:
        running.stop()
