"""The parameter files shipped in `params/`, generated from the named settings.

`default.par` is the built-in preset (P-, PI (3.0, 30) and (2.7, 40), 100 ms);
`minphase.par` and `nonminphase.par` are the paper's P- and P+ with the thesis's
decentralized PI controllers; `coupled-cascade.par`, `coupled-tito.par` and
`desautel-qtp.par` the other rigs (core.plants) at their published operating points.  A test checks the committed files equal this
module's output, so the files and the code cannot drift apart.  Regenerate with
``python -m quadtank_tui.files.shipped params``.
"""

from __future__ import annotations

import sys
from datetime import datetime
from pathlib import Path

from quadtank_tui.core.parameters import NAMED_SETTINGS, PLANT_SETTINGS, PRESET, Parameters
from quadtank_tui.files.par import SUFFIX, write_par

#: The `Created on:` stamp of the shipped files (fixed, so regenerating is a no-op).
SHIPPED_STAMP = datetime(2026, 11, 21, 5, 0, 0)


def shipped_settings() -> dict[str, Parameters]:
    """File name (without `.par`) -> parameters."""
    return {"default": PRESET, **NAMED_SETTINGS, **PLANT_SETTINGS}


def write_shipped(folder: Path | str) -> list[Path]:
    """Write every shipped file into `folder` (bypassing the reserved-name guard
    of ParStore.save on purpose: this is the administrator's path)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [write_par(folder / f"{name}{SUFFIX}", p, created=SHIPPED_STAMP) for name, p in shipped_settings().items()]


if __name__ == "__main__":  # pragma: no cover
    for written in write_shipped(sys.argv[1] if len(sys.argv) > 1 else "params"):
        print(written)
