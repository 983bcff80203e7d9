"""Identify a process from one or more records: find which input moved in each,
fit the elements (step, oe, arx) or a MIMO model (n4sid), validate, and assemble
the transfer matrix.

SIMO records (one input excited per record, the thesis's way) are combined: the
element from input i to output o comes from the record in which input i moves.  A
record in which two of the chosen inputs move (MIMO) feeds the subspace method or
an output-error fit of each output's elements together; step and ARX fits refuse
it (a per-element fit would take the other input's effect for noise).

The operating point is the first row of each record (our experiment scripts log
one sample of rest before the excitation starts); models work in deviations from it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from scipy import signal

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.arx import fit_arx
from quadtank_tui.core.identify.oe import fit_oe, fit_oe_miso, simulate_oe
from quadtank_tui.core.identify.step import STRUCTURES, find_steps, fit_step, simulate_steps
from quadtank_tui.core.identify.subspace import fit_subspace
from quadtank_tui.core.identify.system import SystemModel, from_elements, from_state_space, time_constants
from quadtank_tui.core.identify.validation import (
    autocorrelation, cross_correlation, fit_percent, split_index,
)

METHODS = ("step", "oe", "n4sid", "arx")
INPUTS = ("u1", "u2")
OUTPUTS = ("y1", "y2")
MIN_ROWS = 50


@dataclass(frozen=True)
class Record:
    """One experiment: named columns sampled every h s (a log's content)."""

    name: str
    h: float
    columns: Mapping[str, np.ndarray]

    @property
    def rows(self) -> int:
        return len(next(iter(self.columns.values())))

    def column(self, key: str) -> np.ndarray:
        if key not in self.columns:
            raise IdentificationError(f"{self.name}: no column {key!r} (logged: {' '.join(self.columns)})")
        return np.asarray(self.columns[key], dtype=float)

    def moves(self, key: str) -> bool:
        u = self.column(key)
        return bool(np.ptp(u) > 1e-9 * max(1.0, float(np.abs(u).max())))


@dataclass(frozen=True)
class Options:
    """What to fit.  `order`: poles of an oe element (default 1 on the diagonal, 2
    off it: the path through an upper tank), na = nb of arx (default 2), states of
    n4sid (default 4).  `n`: the step structures' n (None tries 1..4).  `start`:
    manual starting values, T and L (step: T a number; oe: T a list, one per pole)."""

    method: str = "oe"
    inputs: tuple[str, ...] | None = None
    outputs: tuple[str, ...] | None = None
    structure: int = 1
    n: int | None = None
    order: int | None = None
    zeros: int = 0
    delay: bool = True
    fraction: float = 0.5
    start: dict[str, Any] | None = None


@dataclass(frozen=True)
class Element:
    """One fitted element with its validation figures.  `y`, `ym` are the whole
    record's output and model output; `split` the first validation row."""

    output: str
    input: str
    record: str
    tf: DelayTF
    kind: str
    params: dict[str, Any]
    loss: float
    fit_percent: float
    whiteness: float
    independence: float
    split: int
    y: np.ndarray = field(repr=False)
    ym: np.ndarray = field(repr=False)
    u: np.ndarray = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {
            "output": self.output, "input": self.input, "log": self.record, "model": self.kind,
            **self.params,
            "num": list(self.tf.num), "den": list(self.tf.den), "delay": self.tf.delay,
            "static_gain": self.tf.static_gain, "time_constants": time_constants(self.tf),
            "loss": self.loss, "fit_percent": self.fit_percent,
            "residual_whiteness": self.whiteness, "residual_input_independence": self.independence,
        }


@dataclass(frozen=True)
class Identification:
    """The result: elements by (output, input), the system, per-output fit, the
    operating point (first row of the first record used)."""

    method: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    elements: dict[tuple[str, str], Element]
    system: SystemModel
    fit_percent: dict[str, float]
    operating_point: dict[str, float]
    records: tuple[str, ...]
    h: float


def _choose(records: Sequence[Record], opts: Options) -> tuple[tuple[str, ...], tuple[str, ...]]:
    if not records:
        raise IdentificationError("no log given")
    for r in records:
        if r.rows < MIN_ROWS:
            raise IdentificationError(f"{r.name}: too few rows to identify from: {r.rows} (need {MIN_ROWS})")
    outputs = opts.outputs or tuple(y for y in OUTPUTS if all(y in r.columns for r in records))
    if not outputs:
        raise IdentificationError(f"{records[0].name}: no output column (y1 or y2) in every log")
    for r in records:
        for y in outputs:
            r.column(y)
    if opts.inputs:
        inputs = opts.inputs
        for i in inputs:
            present = [r for r in records if i in r.columns]
            if not present:
                raise IdentificationError(f"{records[0].name}: no column {i!r}")
            if not any(r.moves(i) for r in present):
                raise IdentificationError(f"{i} is constant in {', '.join(r.name for r in present)}: "
                                          "nothing to identify from")
    else:
        inputs = tuple(i for i in INPUTS if any(i in r.columns and r.moves(i) for r in records))
        if not inputs:
            raise IdentificationError(f"{', '.join(r.name for r in records)}: no input moves "
                                      "(u1 and u2 are constant)")
    return inputs, outputs


def identify(records: Sequence[Record], opts: Options = Options(),
             cancel: Callable[[], bool] | None = None) -> Identification:
    """Fit the records as `opts` says; `cancel()` True stops between elements."""
    if opts.method not in METHODS:
        raise IdentificationError(f"method must be one of {', '.join(METHODS)}, got {opts.method!r}")
    inputs, outputs = _choose(records, opts)
    if opts.method == "n4sid":
        return _identify_mimo(records, inputs, outputs, opts)
    elements: dict[tuple[str, str], Element] = {}
    used: list[str] = []
    op: dict[str, float] = {}
    for i in inputs:
        if any(key[1] == i for key in elements):
            continue  # fitted with the other inputs of its MIMO record
        rec = _record_for(records, i, inputs, opts.method)
        if rec.name not in used:
            used.append(rec.name)
        moving = [j for j in inputs if j in rec.columns and rec.moves(j)]
        for o in outputs:
            if cancel is not None and cancel():
                raise IdentificationError("cancelled")
            if len(moving) > 1:
                elements.update(_fit_miso(rec, moving, o, opts))
            else:
                elements[(o, i)] = _fit_element(rec, i, o, opts)
        if not op:
            op = {k: float(rec.column(k)[0]) for k in (*inputs, *outputs) if k in rec.columns}
    system = from_elements([[elements[(o, i)].tf for i in inputs] for o in outputs])
    fits = {o: _pooled_fit([elements[(o, i)] for i in inputs]) for o in outputs}
    return Identification(opts.method, inputs, outputs, elements, system, fits, op, tuple(used), records[0].h)


def _record_for(records: Sequence[Record], i: str, inputs: Sequence[str], method: str) -> Record:
    """The first record in which input i moves; step and arx need it to be the only
    chosen input that moves there."""
    for r in records:
        if i in r.columns and r.moves(i):
            others = [j for j in inputs if j != i and j in r.columns and r.moves(j)]
            if others and method != "oe":
                raise IdentificationError(
                    f"{r.name}: {i} and {others[0]} both move; a per-element fit needs one moving "
                    "input per log (a SIMO experiment): use --method n4sid or oe")
            return r
    raise IdentificationError(f"{i} does not move in any log")


def _validate(u: np.ndarray, y: np.ndarray, ym: np.ndarray, k: int) -> tuple[float, float, float]:
    """fit %, and the shares of residual auto- and input cross-correlation lags inside
    the 99 % band, on the validation part (rows k..)."""
    e = y[k:] - ym[k:]
    if np.ptp(e) == 0:
        return fit_percent(y[k:], ym[k:]), 1.0, 1.0
    uu = u[k:]
    cross = cross_correlation(uu, e).inside if np.ptp(uu) > 0 else 1.0
    return fit_percent(y[k:], ym[k:]), autocorrelation(e).inside, cross


def _fit_element(rec: Record, i: str, o: str, opts: Options) -> Element:
    u, y, h = rec.column(i), rec.column(o), rec.h
    k = split_index(rec.rows, opts.fraction)
    end = k if k else rec.rows
    ui, yi = u[:end], y[:end]
    if np.ptp(ui) == 0:
        raise IdentificationError(f"{rec.name}: {i} does not move in the identification part "
                                  f"(the first {end} rows); give a larger --validate fraction")
    if opts.method == "step":
        sf = fit_step(ui, yi, h, opts.structure, opts.n, start=opts.start)
        ym = simulate_steps(sf.model, h, rec.rows, find_steps(u), sf.y0, sf.k0)
        tf, loss = sf.model.tf(), sf.loss
        params = {"structure": sf.model.structure, "form": STRUCTURES[sf.model.structure],
                  **sf.model.params(), "y0": sf.y0, "k0": sf.k0}
    elif opts.method == "oe":
        order = opts.order or (1 if i[1:] == o[1:] else 2)
        of = fit_oe(ui, yi, h, order, opts.zeros, delay=opts.delay, u0=u[0], start=opts.start)
        ym = simulate_oe(of.model, u, h, u[0], of.offset)
        tf, loss = of.model.tf(), of.loss
        params = {"poles": order, "zeros": opts.zeros, **of.model.params(), "offset": of.offset}
    else:
        order = opts.order or 2
        af = fit_arx(ui, yi, h, order, order, 1, u0=u[0], y0=y[0])
        ym = y[0] + signal.lfilter(af.b, af.a, u - u[0])
        if af.tf is None:
            raise IdentificationError(f"{rec.name}: the ARX model of {o}/{i} has a pole on the negative "
                                      "real axis (no continuous-time equivalent): try --order 1 or --method oe")
        tf, loss = af.tf, af.loss
        params = {"na": order, "nb": order, "nk": 1, "a": af.a.tolist(), "b": af.b.tolist()}
    fp, white, indep = _validate(u - u[0], y, ym, k)
    return Element(o, i, rec.name, tf, opts.method, params, loss, fp, white, indep, k, y, ym, u)


def _fit_miso(rec: Record, inputs: Sequence[str], o: str, opts: Options) -> dict[tuple[str, str], Element]:
    """One output's elements from a MIMO record, fitted together (output error)."""
    U = np.column_stack([rec.column(i) for i in inputs])
    y, h = rec.column(o), rec.h
    k = split_index(rec.rows, opts.fraction)
    end = k if k else rec.rows
    orders = [opts.order or (1 if i[1:] == o[1:] else 2) for i in inputs]
    mf = fit_oe_miso(U[:end], y[:end], h, orders, opts.zeros, delay=opts.delay, u0=U[0])
    ym = mf.offset + sum((simulate_oe(g, U[:, j], h, U[0, j], 0.0) for j, g in enumerate(mf.models)),
                         np.zeros_like(y))
    out = {}
    for j, (i, g) in enumerate(zip(inputs, mf.models)):
        fp, white, indep = _validate(U[:, j] - U[0, j], y, ym, k)
        params = {"poles": orders[j], "zeros": opts.zeros, **g.params(), "offset": mf.offset,
                  "fitted_with": list(inputs)}
        out[(o, i)] = Element(o, i, rec.name, g.tf(), "oe", params, mf.loss, fp, white, indep, k, y, ym, U[:, j])
    return out


def _pooled_fit(elements: Sequence[Element]) -> float:
    """One output's fit over the validation parts of all its records together."""
    ys = np.concatenate([e.y[e.split:] for e in elements])
    yms = np.concatenate([e.ym[e.split:] for e in elements])
    return fit_percent(ys, yms)


def _identify_mimo(records: Sequence[Record], inputs: Sequence[str], outputs: Sequence[str],
                   opts: Options) -> Identification:
    rec = next((r for r in records if all(i in r.columns and r.moves(i) for i in inputs)), None)
    if rec is None:
        raise IdentificationError(
            f"n4sid needs a log in which {' and '.join(inputs)} all move (a MIMO experiment); "
            "for SIMO logs use --method oe")
    U = np.column_stack([rec.column(i) for i in inputs])
    Y = np.column_stack([rec.column(o) for o in outputs])
    k = split_index(rec.rows, opts.fraction)
    end = k if k else rec.rows
    sf = fit_subspace(U[:end], Y[:end], rec.h, opts.order or 4, u0=U[0], y0=Y[0])
    Ym = Y[0] + sf.simulate(U - U[0])
    system = from_state_space(sf.A, sf.B, sf.C)
    elements = {}
    for a, o in enumerate(outputs):
        for b, i in enumerate(inputs):
            # Each element's own share: the output with only input i moving.
            fp, white, indep = _validate(U[:, b] - U[0, b], Y[:, a], Ym[:, a], k)
            tf = system.elements[a][b]
            assert tf is not None  # from_state_space fills every element
            elements[(o, i)] = Element(
                o, i, rec.name, tf, "n4sid",
                {"states": sf.A.shape[0], "singular_values": sf.singular_values.tolist()},
                float(sf.loss[a]), fp, white, indep, k, Y[:, a], Ym[:, a], U[:, b])
    fits = {o: fit_percent(Y[k:, a], Ym[k:, a]) for a, o in enumerate(outputs)}
    op = {key: float(rec.column(key)[0]) for key in (*inputs, *outputs)}
    return Identification("n4sid", tuple(inputs), tuple(outputs), elements, system, fits, op,
                          (rec.name,), rec.h)
