"""Which physics a physical fit needs, chosen from the logs.

A plain Torricelli model fitted to our own simulator's logs reaches the noise of the
readings and needs nothing more; a real rig's logs leave a residual well above it
(laminar outlet flow, an upper tank that overflows into the lower one).  The
choice: fit the plain model (with the sensor range when a reading sits at the end
of its range); if it is not at the noise of the readings, fit it again with every
effect of the plant kind that the logs can show (laminar outflow, overflow) and keep
that one if it is better by Schwarz's criterion (BIC: N ln(SSE / N) + p ln N, so a
constant must pay for itself) and by at least :data:`GAIN` of the RMS.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np

from quadtank_tui.core.identify.physical import (
    BUDGET_S,
    NOISE_MARGIN,
    Experiment,
    PhysicalFit,
    FULL_SCALE_V,
    MAX_EVALUATIONS,
    ProgressFn,
    cpu_clock,
    fit_physical,
    noise_floor,
    physics_names,
)
from quadtank_tui.core.plants import Plant

#: An extended model must lower the RMS by this fraction to be kept.
GAIN = 0.05
#: A reading is at the end of its sensor's range when this many samples (and 1 % of
#: the log) lie within :data:`PLATEAU_V` of its highest value.
PLATEAU_ROWS = 5
PLATEAU_V = 0.01
#: The effects tried when the plain model is not at the noise.
EXTENDED = ("laminar", "overflow")


def saturated_outputs(experiments: Sequence[Experiment]) -> list[int]:
    """The outputs whose readings sit at their highest value for a while, as a sensor
    at the end of its range does: near the input's full scale (9.5 V and up), or,
    in readings that are noisy elsewhere, exactly still there (a level that settles
    keeps its noise)."""
    out = []
    for j, o in enumerate(experiments[0].outputs):
        y = np.concatenate([e.y[:, j] for e in experiments])
        top = float(y.max())
        near = y >= top - PLATEAU_V
        if int(near.sum()) < max(PLATEAU_ROWS, 0.01 * y.size) or np.ptp(y) <= 20 * PLATEAU_V:
            continue
        still = int(np.sum(y == top)) >= 2 * PLATEAU_ROWS
        noisy = noise_floor([Experiment(e.name, e.h, e.u, e.y[:, [j]], (o,)) for e in experiments]) > 1e-4
        if top >= 0.95 * FULL_SCALE_V or (still and noisy):
            out.append(o)
    return out


def bic(fit: PhysicalFit) -> float:
    n = sum(e.y.size for e in fit.experiments)
    p = len(fit.constants) + len(fit.offsets) + sum(len(x) for x in fit.initial)
    return n * math.log(max(fit.rms, 1e-300) ** 2) + p * math.log(n)


def fit_auto(plant: Plant, experiments: Sequence[Experiment], free: Sequence[str] | None = None, *,
             offsets: bool = True, progress: ProgressFn | None = None, budget_s: float = BUDGET_S,
             max_evaluations: int | None = None) -> PhysicalFit:
    """The plain fit, or the extended one when the logs ask for it (the note says which)."""
    from time import monotonic

    t0, c0 = monotonic(), cpu_clock()
    limit = max_evaluations or MAX_EVALUATIONS
    sat = tuple("saturation" for _ in saturated_outputs(experiments)[:1])
    plain = fit_physical(plant, experiments, free, offsets=offsets, progress=progress, physics=sat,
                         budget_s=budget_s / 2.0, max_evaluations=limit)
    floor = noise_floor(experiments)
    words = ["sensor range"] if sat else []
    if plain.rms <= NOISE_MARGIN * floor or plain.message.startswith("cancelled"):
        return replace(plain, notes=plain.notes + (_note("plain", words, plain, floor),))
    outputs = experiments[0].outputs
    more = [p for p in EXTENDED if physics_names(plant, (p,), outputs)]
    if not more:
        return replace(plain, notes=plain.notes + (_note("plain", words, plain, floor),))
    left = budget_s - (cpu_clock() - c0)
    ext = fit_physical(plant, experiments, free, offsets=offsets, progress=progress, physics=sat + tuple(more),
                       budget_s=max(left, 1.0), starts=tuple(overflow_starts(plain)), max_evaluations=limit)
    if bic(ext) < bic(plain) and ext.rms < (1 - GAIN) * plain.rms:
        note = _note("extended", words + list(more), ext, floor) + f" (plain model: RMS {plain.rms:.4g} V)"
        return replace(ext, notes=ext.notes + (note,), seconds=monotonic() - t0)
    note = _note("plain", words, plain, floor) + f"; with {', '.join(more)}: RMS {ext.rms:.4g} V, not kept"
    return replace(plain, notes=plain.notes + (note,), seconds=monotonic() - t0)


#: Where the plain fit's upper level would have to spill (its percentiles), and the
#: shares of the spill that reach the lower tank, of the overflow starts.
BRIM_PERCENTILES = (60.0, 80.0, 95.0)
SPILL_SHARES = (0.3, 0.7)


def overflow_starts(plain: PhysicalFit) -> list[tuple[str, dict[str, float]]]:
    """Starts of the cascade with overflow from the plain fit: its constants, with
    the upper tank's cross-section (area1) put where its brim falls at a high
    percentile of the levels the plain model gives the upper tank (where a real rig's
    tank would have spilled instead), and its outlet restated for that area.  A fit
    with overflow from the `.par`'s or from random constants rarely finds that
    basin: with the upper tank far from its brim the overflow does nothing and the
    fit slides into a slow upper tank instead."""
    from quadtank_tui.core.identify.physical import simulate

    p = plain.plant
    if p.kind != "coupled-cascade":
        return []
    v = p.values()
    x1 = np.concatenate([simulate(p, x0, e.u, e.h)[:, 0] for e, x0 in zip(plain.experiments, plain.initial)])
    top = p.states[0].hi
    out = []
    for q in BRIM_PERCENTILES:
        area = max(float(np.percentile(x1, q)) / top, 0.02)
        for share in SPILL_SHARES:
            start = {e.name: e.value for e in plain.constants}
            start.update(area1=area, spill1=share, alpha1=v["alpha1"] * math.sqrt(area),
                         lam1=v.get("lam1", 0.0) * area, lam2=v.get("lam2", 0.0))
            start.update({f"off{e.name[1]}": e.value for e in plain.offsets})
            out.append((f"the plain fit spilling at its {q:g}th percentile ({share:g} falling below)", start))
    return out


def _note(which: str, words: Sequence[str], fit: PhysicalFit, floor: float) -> str:
    physics = "Torricelli outlets" + "".join(f", {w}" for w in words)
    return (f"physics: {physics} (chosen from the logs: RMS {fit.rms:.4g} V, readings' noise about "
            f"{floor:.2g} V)")
