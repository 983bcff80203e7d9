"""The Identify screen's method "physical" (issue 27): the constants of the plant in
use fitted by its own simulator to the ticked logs (core.identify.physical), the
last ticked log held out for validation when two or more are ticked.

What runs in the worker (:func:`compute_physical`: read, fit, validate) and what the
screen shows of it (:func:`constant_rows`, :func:`overlay`) live here; the screen
only calls them.  Saving writes the fitted constants into a copy of the `.par` in
use, as `quadtank identify --method physical --save` does (files.physical_par).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

if TYPE_CHECKING:
    from quadtank_tui.core.identify.crossval import Figure
    from quadtank_tui.core.identify.physical import Experiment, PhysicalFit
    from quadtank_tui.core.plants import Plant


@dataclass(frozen=True)
class PhysicalView:
    """A finished physical fit: the fit, the plant it started from, and the held-out
    log (None when one log was ticked) with its figures and predicted sensors (V)."""

    fit: PhysicalFit
    start: Plant
    fitted_logs: tuple[str, ...]
    validation: Experiment | None
    figures: tuple[Figure, ...]
    predicted: np.ndarray | None


def default_free(plant: Plant) -> tuple[str, ...]:
    """The constants ticked at first: those a lab does not measure with a ruler."""
    from quadtank_tui.core.identify.physical import DEFAULT_FREE

    return DEFAULT_FREE.get(plant.kind, ())


def evaluations_bound(free: int, outputs: int) -> int:
    """An upper bound of the simulations a fit runs (the progress bar's total): the
    solver's limit times one run per free constant and one more."""
    from quadtank_tui.core.identify.physical import MAX_EVALUATIONS

    return MAX_EVALUATIONS * (free + 1) + outputs


def compute_physical(paths: list[str], plant: Plant, free: tuple[str, ...], cancel: threading.Event,
                     progress: Callable[[int, float], None] = lambda k, rms: None) -> PhysicalView:
    """Read the logs, fit `free` on all but the last of two or more (the last is held
    out), validate there (run in a worker; IdentificationError "cancelled" when
    `cancel` is set)."""
    from quadtank_tui.core.identify.physical import experiment_from_columns, fit_physical, validate_physical
    from quadtank_tui.files.log_reader import read_log

    logs = []
    for p in paths:
        log = read_log(p)
        if log.tsamp is None:
            raise ValueError(f"{p}: no TSamp in the header: the sampling time is needed")
        logs.append((p, log.tsamp, log.columns()))
    fit_on = logs[:-1] if len(logs) > 1 else logs
    fitted = [experiment_from_columns(p, h, cols, plant) for p, h, cols in fit_on]

    def tick(k: int, rms: float) -> bool:
        progress(k, rms)
        return not cancel.is_set()

    fit = fit_physical(plant, fitted, free, progress=tick)
    held: Experiment | None = None
    figures: tuple[Figure, ...] = ()
    predicted: np.ndarray | None = None
    if len(logs) > 1:
        p, h, cols = logs[-1]
        held = experiment_from_columns(p, h, cols, plant, [f"y{o + 1}" for o in fitted[0].outputs])
        figs, predicted, _ = validate_physical(fit.plant, held, [o.value for o in fit.offsets])
        figures = tuple(figs)
    return PhysicalView(fit, plant, tuple(e.name for e in fitted), held, figures, predicted)


def constant_rows(view: PhysicalView) -> list[tuple[str, str, str, str, str]]:
    """(constant, fitted, +-, the .par's value, unit) of each fitted constant."""
    units = view.start.units
    before = view.start.values()
    return [(e.name, f"{e.value:.6g}", f"{e.stderr:.2g}", f"{before[e.name]:.6g}", units.get(e.name, ""))
            for e in view.fit.constants]


def overlay(view: PhysicalView, index: int) -> tuple[str, np.ndarray, np.ndarray, np.ndarray, str]:
    """(output name, t, measured, model, title) of output `index` on the held-out log
    (the first fitted log when none is held out); voltages in V."""
    if view.validation is not None and view.predicted is not None:
        exp, ym, where = view.validation, view.predicted, "validation"
    else:
        exp, ym, where = view.fit.experiments[0], view.fit.predicted[0], "fitted"
    j = index % len(exp.outputs)
    name = f"y{exp.outputs[j] + 1}"
    t = np.arange(exp.rows) * exp.h
    return name, t, exp.y[:, j], ym[:, j], f"{Path(exp.name).name} ({where})"


def summary(view: PhysicalView) -> str:
    """The status line after a fit: RMS, and the validation figures."""
    text = f"physical: {len(view.fit.constants)} constants, RMS {view.fit.rms:.3g} V over {len(view.fitted_logs)} log(s)"
    if view.figures:
        text += "; validation " + "  ".join(f"{f.output} {f.fit_percent:.1f} % (RMS {f.rms_v:.3g} V)"
                                            for f in view.figures)
    return text


def save_par(view: PhysicalView, par_text: str, target: Path) -> Path:
    """The fitted constants in a copy of `par_text` (the `.par` in use) at `target`."""
    from quadtank_tui.files.atomic import atomic_write_text
    from quadtank_tui.files.physical_par import with_fit

    fit = view.fit
    notes = {e.name: f"+- {e.stderr:.3g} (1 standard error); was {e.start:.8g}" for e in fit.constants}
    header = [f"Constants fitted on the Identify screen (physical) to {', '.join(view.fitted_logs)}",
              f"RMS output error {fit.rms:.4g} V"]
    atomic_write_text(target, with_fit(par_text, str(target), fit.plant, notes, header), encoding="utf-8")
    return target


def par_target(view: PhysicalView) -> Path:
    """NAME.par next to the first fitted log."""
    first = Path(view.fitted_logs[0])
    return first.with_name(first.name.removesuffix(".log") + ".par")
