"""LoadPar without the disk on the loop's thread.

A `.par` in a home folder on a slow NFS server can take seconds to read; read on
the loop's thread, those seconds are samples the rig does not get.  So a driver
that samples (the engine's thread, a session) starts the read on a thread of its
own (`ParReading.start`) and keeps sampling; the commands that came after the
LoadPar wait behind it, in order, and once the file is read and checked the loop
only installs the parameters (InstallPar).  A bad file gives the refusal the
loop would have given (file:line and why: prepare_load).
"""

from __future__ import annotations

import threading
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Callable

from quadtank_tui.engine.commands import CommandResult, InstallPar, LoadPar
from quadtank_tui.engine.outcome import refusal
from quadtank_tui.files.par import ParStore


def prepare_load(store: ParStore, cmd: LoadPar) -> InstallPar | CommandResult:
    """Read and check the `.par` a LoadPar names (no loop state touched: any thread);
    its refusal (file:line and why) if it cannot be loaded."""
    try:
        read = store.load(cmd.name)
    except Exception as exc:  # noqa: BLE001 - as begin() and Engine._drain would say it
        return refusal(exc) or CommandResult.refused(f"LoadPar failed: {type(exc).__name__}: {exc}")
    return InstallPar(cmd.name, read.params, tuple(read.warnings))


@dataclass(frozen=True)
class ParReading:
    """A LoadPar whose file a thread of its own reads; `future` holds the
    InstallPar, or the refusal."""

    name: str
    future: Future[InstallPar | CommandResult]

    @classmethod
    def start(cls, store: ParStore, cmd: LoadPar, wake: Callable[[], None]) -> ParReading:
        """Start reading; `wake()` is called (from the reader's thread) once it is done."""
        fut: Future[InstallPar | CommandResult] = Future()

        def read() -> None:
            try:
                fut.set_result(prepare_load(store, cmd))
            except BaseException as exc:  # noqa: BLE001 - never leave the commands behind it waiting
                fut.set_result(CommandResult.refused(f"LoadPar failed: {type(exc).__name__}: {exc}"))
            wake()

        threading.Thread(target=read, name="quadtank-par-read", daemon=True).start()
        return cls(cmd.name, fut)

    @property
    def done(self) -> bool:
        return self.future.done()
