"""Log rows go to the file thread in batches (engine/filework.py): at x1000 one job
and one write(2) of about 20 rows a millisecond instead of a Future, a queue put, a
wake-up and a write a row; in order with the other file operations, and never held
while the loop waits."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any, Callable

import pytest

from quadtank_tui.engine.commands import LogOn, LogSave, SetState
from quadtank_tui.engine import filework
from quadtank_tui.engine.filework import FileWorker
from quadtank_tui.engine.runner import Engine


def test_items_of_one_window_go_to_one_call_in_order_with_the_others() -> None:
    worker = FileWorker()
    worker.start_thread()
    calls: list[tuple[str, Any]] = []
    worker._handed = float("inf")  # noqa: SLF001 - the window never ends: nothing goes until a flush

    def rows(items: list[int]) -> None:
        calls.append(("rows", list(items)))

    for k in range(5):
        worker.submit_batched(rows, k)
    assert calls == []                                   # held
    worker.submit(lambda: calls.append(("save", None))).result(5)  # a save comes after the rows before it
    worker.submit_batched(rows, 5)
    assert worker.drain(5)
    assert calls == [("rows", [0, 1, 2, 3, 4]), ("save", None), ("rows", [5])]
    worker.close()


def test_an_item_after_the_window_goes_at_once_and_a_failure_stops_nothing() -> None:
    worker = FileWorker()
    worker.start_thread()
    ran = threading.Event()
    seen: list[int] = []

    def fails(items: list[int]) -> None:
        raise OSError("the caller keeps its own failure")

    def kept(items: list[int]) -> None:
        seen.extend(items)
        ran.set()

    worker.submit_batched(fails, 1)                # the first: the last hand-off was never
    worker.submit_batched(kept, 2)
    worker._handed = -float("inf")  # noqa: SLF001 - the window is over
    worker.submit_batched(kept, 3)
    assert ran.wait(5) and worker.drain(5)
    assert seen == [2, 3]
    worker.close()


def test_inline_items_run_at_once() -> None:
    worker = FileWorker()
    seen: list[list[int]] = []
    worker.submit_batched(seen.append, 7)
    assert seen == [[7]]


def test_a_threaded_log_written_in_batches_is_the_inline_log_row_for_row(
        make_engine: Callable[..., Engine], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def logs(engine: Engine, name: str) -> list[bytes]:
        engine.submit(SetState("Run"))
        assert engine.submit(LogOn(points=250)).result(5).ok
        engine.run_for(25.0)                           # 250 samples of 0.1 s, all logged
        assert engine.submit(LogSave(name)).result(10).ok
        text = (tmp_path / "logs" / f"{name}.log").read_bytes()
        return [line for line in text.splitlines() if line and not line.startswith(b"%")]

    expected = logs(make_engine(), "inline")
    threaded = make_engine()
    threaded.loop.use_file_thread()
    batches: list[int] = []
    monkeypatch.setattr(filework, "BATCH_WINDOW", 1e9)  # only the first row goes on its own
    monkeypatch.setattr(FileWorker, "flush", _counting(FileWorker.flush, batches))
    got = logs(threaded, "threaded")
    assert len(expected) == 250 and got == expected
    # The first row at once, the other 249 when the drive ended (the driver's last
    # flush): nothing is held once the loop stops sampling.
    assert batches == [1, 249]


def _counting(flush: Callable[[FileWorker], None], calls: list[int]) -> Callable[[FileWorker], None]:
    def counted(self: FileWorker) -> None:
        if self._batch:  # noqa: SLF001
            calls.append(len(self._batch))  # noqa: SLF001
        flush(self)
    return counted


def test_an_inline_drive_writes_its_rows_in_batches_and_holds_none_when_it_ends(
        make_engine: Callable[..., Engine], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # quadtank run as fast as possible: the rows of a BATCH_WINDOW go in one
    # write(2), as to the file thread; once the drive is over, every row is in the
    # partial file (a reader, a crash, the next LoadPar find them all).
    engine = make_engine()
    engine.submit(SetState("Run"))
    assert engine.submit(LogOn(points=1000)).result(5).ok
    batches: list[int] = []
    monkeypatch.setattr(filework, "BATCH_WINDOW", 1e9)  # only the first row goes on its own
    monkeypatch.setattr(FileWorker, "flush", _counting(FileWorker.flush, batches))
    engine.run_for(30.0)                                   # 300 samples of 0.1 s
    assert batches == [1, 299]
    assert not engine.loop.files.batches                   # inline and at once again
    partial = next((tmp_path / "logs").glob("*.partial"))
    rows = [line for line in partial.read_bytes().splitlines() if line and not line.startswith(b"%")]
    assert len(rows) == 300
    engine.loop.step()                                     # a step outside a drive: written at once
    rows = [line for line in partial.read_bytes().splitlines() if line and not line.startswith(b"%")]
    assert len(rows) == 301


def test_a_paced_drive_keeps_its_rows_through_waits_shorter_than_a_batch(
        make_engine: Callable[..., Engine], monkeypatch: pytest.MonkeyPatch) -> None:
    # x1000 at 0.1 s: a sample every 100 us of wall time, each wait a few tens of
    # us.  Handing the rows on before every such wait woke the file thread every
    # sample and undid the batches; now only a wait of FLUSH_BEFORE or more does.
    engine = make_engine(clock="virtual", speed=1000.0)
    engine.submit(SetState("Run"))
    assert engine.submit(LogOn(points=1000)).result(5).ok
    batches: list[int] = []
    monkeypatch.setattr(filework, "BATCH_WINDOW", 1e9)  # only the first row goes on its own
    monkeypatch.setattr(FileWorker, "flush", _counting(FileWorker.flush, batches))
    engine.run_for(30.0)                                   # 300 samples, 30 ms of wall time
    assert engine.loop.files.threaded                      # paced on the wall: the file thread
    assert batches == [1, 299]
