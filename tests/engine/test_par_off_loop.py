"""LoadPar on an engine driven inline reads the `.par` on the spot: a bad file gives
the message it always gave (file:line and why) and the parameters stay.  A session
reads it off the driver's thread (engine/parload.py): tests/session/
test_session_loadpar.py holds the read that hangs, the order and the same message."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.engine.commands import LoadPar, SavePar, SetParams
from quadtank_tui.engine.runner import Engine, build_engine

K = "CONTROLLER ONE.K"



def engine_with_a_par(tmp_path: Path) -> Engine:
    e = build_engine(clock="virtual", speed=50.0, params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    assert e.submit(SetParams({K: 2.5})).result().ok
    assert e.submit(SavePar("mine", overwrite=True)).result().ok
    assert e.submit(SetParams({K: 1.0})).result().ok
    return e


BAD = "% TANK PAR-file\n\nSAMPLING TIME\nTSamp fast\n"


@pytest.mark.parametrize("name", ["bad", "missing"])
def test_a_bad_file_gives_the_same_message(name: str, tmp_path: Path) -> None:
    """The message names the file (and line and value); the parameters in force stay."""
    inline = engine_with_a_par(tmp_path)
    (tmp_path / "params" / "bad.par").write_text(BAD)
    said = inline.submit(LoadPar(name)).result()
    assert not said.ok
    assert said.message.startswith(str(tmp_path / "params" / f"{name}.par"))
    if name == "bad":
        assert "line 4" in said.message and "fast" in said.message, said.message
    assert inline.snapshot().params.get(K) == 1.0
    inline.stop()
