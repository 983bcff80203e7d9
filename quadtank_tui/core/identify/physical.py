"""Physical-parameter identification: fit the constants of the plant in use by
minimizing the simulation (output) error of its own nonlinear model over logs.

The model simulated is the plant's :meth:`~quadtank_tui.core.plants.base.Plant.advance`
(the simulator itself, not a copy): each log is simulated open loop from its
initial levels with the logged pump voltages held over each sample, and the
sensor voltages it predicts, plus an optional offset per sensor, are compared with
the logged ones.  scipy's trust-region least squares (``least_squares``, method
"trf") minimizes the sum of squared errors in V over:

- the free constants (default: those a lab does not measure with a ruler, see
  :data:`DEFAULT_FREE`), within bounds from the physics (a valve split in [0, 1],
  an outlet smaller than its tank, a pump coefficient > 0);
- the initial level of every tank in every log (unmeasured tanks too);
- optionally one sensor offset per measured output (``"y1.offset"``, V).

The Jacobian is taken by forward differences, log by log (an initial level moves
only its own log).  The uncertainty of each constant is its standard error from
that Jacobian at the optimum: sqrt(diag(s^2 (J^T J)^-1)), s^2 = SSE / (N - p).

A sensor gain and the flow constants cannot both be free on level data alone
(scaling the gain by c is undone by scaling the pump coefficients by c and the
outlets by sqrt(c)), which is why the gains are fixed by default: the lab
calibrates them against a ruler (Setup's calibration).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from quadtank_tui.core.identify import IdentificationError
from quadtank_tui.core.identify.crossval import Figure, figure
from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError
from quadtank_tui.core.plants import Plant

#: Constants fitted when none are named: outlets, pumps, valves (not the tank
#: areas, heights, g or sensor gains, which a ruler or a calibration gives).
DEFAULT_FREE: dict[str, tuple[str, ...]] = {
    "quadtank": ("a1", "a2", "a3", "a4", "k1", "k2", "gamma1", "gamma2"),
    "desautel-qtp": ("alpha1", "alpha2", "alpha3", "alpha4", "beta1", "beta2", "beta3", "beta4"),
    "coupled-cascade": ("alpha1", "alpha2", "beta1"),
    "coupled-tito": ("Cd1", "Cd2", "Gp"),
}
#: Sensor gain constants of each plant (free only when asked for).
SENSOR_GAINS: dict[str, tuple[str, ...]] = {
    "quadtank": ("kc",), "desautel-qtp": ("kc",), "coupled-cascade": ("kc1", "kc2"), "coupled-tito": ("Gd",),
}
OFFSET_SUFFIX = ".offset"
#: Relative forward-difference step of the Jacobian, and the solver tolerances.
DIFF_STEP = 1e-6
TOLERANCE = 1e-10
MAX_EVALUATIONS = 60


@dataclass(frozen=True)
class Experiment:
    """One log as the fit sees it: pump voltages u (rows x inputs, V), the measured
    sensor voltages y (rows x len(outputs), V) and which plant outputs they are."""

    name: str
    h: float
    u: np.ndarray
    y: np.ndarray
    outputs: tuple[int, ...]

    @property
    def rows(self) -> int:
        return int(self.u.shape[0])


def experiment_from_columns(name: str, h: float, columns: Mapping[str, np.ndarray], plant: Plant,
                            outputs: Sequence[str] | None = None) -> Experiment:
    """A log's columns (normalized, as logged: 1.0 is a signal's full scale) as an
    experiment of `plant`: every pump must be logged (u1, u2, ...), and the outputs
    (default: every sensor of the plant the log holds)."""
    logged = " ".join(columns)
    u_cols = []
    for i, s in enumerate(plant.inputs):
        key = f"u{i + 1}"
        if key not in columns:
            raise IdentificationError(f"{name}: no column {key} (pump {s.name} of the {plant.kind}); logged: {logged}")
        u_cols.append(np.asarray(columns[key], dtype=float) * s.full_scale)
    extra = [k for k in columns if k.startswith("u") and k[1:].isdigit() and int(k[1:]) > len(plant.inputs)
             and np.ptp(np.asarray(columns[k], dtype=float)) > 0]
    if extra:
        raise IdentificationError(f"{name}: {extra[0]} moves, but a {plant.kind} has {len(plant.inputs)} pump(s): "
                                  "the log is of another kind of plant (--par names the plant)")
    names = [f"y{j + 1}" for j in range(len(plant.outputs))]
    wanted = list(outputs) if outputs else [k for k in names if k in columns]
    if not wanted:
        raise IdentificationError(f"{name}: no sensor column of the {plant.kind} ({' '.join(names)}); logged: {logged}")
    for key in wanted:
        if key not in names:
            raise IdentificationError(f"{name}: a {plant.kind} has no output {key} (it has {' '.join(names)})")
        if key not in columns:
            raise IdentificationError(f"{name}: no column {key}; logged: {logged}")
    y = np.column_stack([np.asarray(columns[k], dtype=float) * FULL_SCALE_V for k in wanted])
    u = np.column_stack(u_cols)
    if u.shape[0] < 10:
        raise IdentificationError(f"{name}: too few rows to fit ({u.shape[0]})")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
        raise IdentificationError(f"{name}: a value is not a number")
    return Experiment(name, float(h), u, y, tuple(names.index(k) for k in wanted))


# --- the simulator, run over a log ---------------------------------------------------------

def simulate(plant: Plant, x0: Sequence[float] | np.ndarray, u: np.ndarray, h: float) -> np.ndarray:
    """Levels at every sample (rows x states): x[0] = x0, then the plant's own ZOH step."""
    x = plant.clip([float(v) for v in x0])
    out = np.empty((u.shape[0], len(x)))
    out[0] = x
    for k in range(1, u.shape[0]):
        x = plant.advance(x, u[k - 1], h)
        out[k] = x
    return out


def sensor_gains(plant: Plant) -> np.ndarray:
    """Volts per level unit of each output (every plant's sensors are linear below
    their range: read at a thousandth of each tank, where none saturates)."""
    low = tuple(1e-3 * s.hi for s in plant.states)
    return np.asarray(plant.output(low), dtype=float) / np.asarray(low)


def predict(plant: Plant, exp: Experiment, x0: Sequence[float] | np.ndarray,
            offsets: Sequence[float] | np.ndarray | None) -> np.ndarray:
    """The sensor voltages the plant predicts for `exp` from levels x0."""
    x = simulate(plant, x0, exp.u, exp.h)
    y = np.array([plant.output(row) for row in x])  # the plant's sensors, with their range
    return y[:, list(exp.outputs)] + _offsets(exp, offsets)


def _offsets(exp: Experiment, offsets: Sequence[float] | np.ndarray | None) -> np.ndarray:
    """The sensor offsets, V (none given: 0 for each output)."""
    return np.zeros(len(exp.outputs)) if offsets is None or len(offsets) == 0 else np.asarray(offsets, float)


def initial_levels(plant: Plant, exp: Experiment, offsets: Sequence[float] | np.ndarray | None = None,
                   rows: int = 1) -> tuple[float, ...]:
    """A first guess of the levels at the log's first row: the measured tanks from
    the mean of the first `rows` readings, the others at the steady state of the
    first input (where a log that starts at rest has them)."""
    gains = sensor_gains(plant)
    try:
        x = list(plant.steady_state(exp.u[0]))
    except PlantError:
        x = [s.hi / 2 for s in plant.states]
    off = _offsets(exp, offsets)
    first = exp.y[:max(1, rows)].mean(axis=0) - off
    for j, o in enumerate(exp.outputs):
        x[o] = float(first[j] / gains[o])
    return plant.clip(x)


# --- the fit ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Estimate:
    """A fitted value with its standard error (inf: the logs do not determine it)."""

    name: str
    value: float
    stderr: float
    start: float


@dataclass(frozen=True)
class PhysicalFit:
    """The result: the plant with the fitted constants, each constant's estimate,
    sensor offsets (V), initial levels per log, and per-log, per-output figures."""

    plant: Plant
    constants: tuple[Estimate, ...]
    offsets: tuple[Estimate, ...]
    initial: tuple[tuple[float, ...], ...]
    experiments: tuple[Experiment, ...] = field(repr=False)
    predicted: tuple[np.ndarray, ...] = field(repr=False)
    rms: float
    evaluations: int

    def fits(self) -> list[Figure]:
        """Fit % and RMS of each output of each log fitted."""
        gains = sensor_gains(self.plant)
        return [figure(exp.name, f"y{o + 1}", exp.y[:, j] / FULL_SCALE_V, ym[:, j] / FULL_SCALE_V, FULL_SCALE_V,
                       float(gains[o]), self.plant.states[o].unit)
                for exp, ym in zip(self.experiments, self.predicted) for j, o in enumerate(exp.outputs)]


def bounds_of(plant: Plant, name: str) -> tuple[float, float]:
    """Where a constant may lie, from the physics of its role."""
    value = float(plant.values()[name])
    if name.startswith("gamma") or name.startswith("spill"):
        return 0.0, 1.0
    if name.startswith("vmin"):  # vmin (the one pump), vmin1, vmin2: below that pump's range
        pump = plant.inputs[int(name[4:]) - 1 if name[4:] else 0]
        return 0.0, pump.hi * (1 - 1e-9)
    if name.startswith("ysat"):
        return 1e-3, math.inf
    if name in plant.outlet_names:
        i = plant.outlet_names.index(name)
        upper = plant.area(i) if name.startswith("a") and plant.area(i) != 1.0 else (
            1.0 if name.startswith(("alpha", "Cd")) else math.inf)
        return value * 1e-6, upper * (1 - 1e-9) if math.isfinite(upper) else upper
    if name.startswith("Cd"):
        return value * 1e-6, 1.0
    return value * 1e-6, math.inf


def _start(plant: Plant, name: str, experiments: Sequence[Experiment]) -> float:
    """A constant's starting value: the plant's, but a sensor range that is off (0)
    starts at the highest reading of that sensor in the logs."""
    value = float(plant.values()[name])
    if name.startswith("ysat") and value == 0.0:
        o = int(name[4:]) - 1
        seen = [float(e.y[:, e.outputs.index(o)].max()) for e in experiments if o in e.outputs]
        if not seen:
            raise IdentificationError(f"{name}: no log measures y{o + 1}, whose range it is")
        return max(seen)
    return value


def _check_free(plant: Plant, free: Sequence[str]) -> None:
    known = plant.values()
    for name in free:
        if name not in known:
            raise IdentificationError(f"a {plant.kind} has no constant {name!r} (it has {', '.join(known)})")
        if name in ("g", "hmax", "vmax", "qmax"):
            raise IdentificationError(f"{name} is not fitted: it is a property of the rig's build, not of its flows")


ProgressFn = Callable[[int, float], bool]


def fit_physical(plant: Plant, experiments: Sequence[Experiment], free: Sequence[str] | None = None, *,
                 offsets: bool = False, progress: ProgressFn | None = None,
                 max_evaluations: int = MAX_EVALUATIONS) -> PhysicalFit:
    """Fit `free` constants of `plant` (default :data:`DEFAULT_FREE`) to the logs.

    `progress(evaluations, rms)` is called after each simulation of all logs; it
    returns False to cancel (IdentificationError "cancelled").  A fit that does not
    converge within `max_evaluations` Jacobians, or ends with a residual worse than
    its start, raises IdentificationError.
    """
    if not experiments:
        raise IdentificationError("no log to fit")
    names = tuple(free) if free is not None else DEFAULT_FREE.get(plant.kind, ())
    if not names and not offsets:
        raise IdentificationError("nothing to fit: name the constants to free")
    _check_free(plant, names)
    n_out = [len(e.outputs) for e in experiments]
    if len(set(tuple(e.outputs) for e in experiments)) != 1:
        raise IdentificationError("every log must hold the same outputs")
    outputs = experiments[0].outputs
    n_states = len(plant.states)
    start_c = [_start(plant, n, experiments) for n in names]
    offs0 = [0.0] * n_out[0] if offsets else []
    x0s = [initial_levels(plant, e) for e in experiments]
    theta0 = np.array(start_c + offs0 + [v for x in x0s for v in x])
    lo = [bounds_of(plant, n)[0] for n in names] + [-FULL_SCALE_V] * len(offs0)
    hi = [bounds_of(plant, n)[1] for n in names] + [FULL_SCALE_V] * len(offs0)
    for _ in experiments:
        lo += [s.lo for s in plant.states]
        hi += [s.hi for s in plant.states]
    lo_a, hi_a = np.array(lo), np.array(hi)
    theta0 = np.clip(theta0, lo_a, hi_a)
    nc, no = len(names), len(offs0)
    calls = [0]

    def unpack(theta: np.ndarray) -> tuple[Plant, np.ndarray]:
        try:
            p = plant.with_values(**{n: float(v) for n, v in zip(names, theta[:nc])})
        except PlantError as exc:
            raise IdentificationError(f"the fit left the physics: {exc}") from None
        return p, (theta[nc:nc + no] if no else np.zeros(n_out[0]))

    def log_residual(p: Plant, off: np.ndarray, j: int, theta: np.ndarray) -> np.ndarray:
        at = nc + no + j * n_states
        e = experiments[j]
        return (predict(p, e, theta[at:at + n_states], off) - e.y).ravel()

    def residual(theta: np.ndarray) -> np.ndarray:
        p, off = unpack(theta)
        r = np.concatenate([log_residual(p, off, j, theta) for j in range(len(experiments))])
        calls[0] += 1
        if progress is not None and not progress(calls[0], float(np.sqrt(np.mean(r * r)))):
            raise IdentificationError("cancelled")
        return r

    sizes = [e.rows * len(e.outputs) for e in experiments]
    starts = np.cumsum([0] + sizes)
    cache: dict[bytes, np.ndarray] = {}

    def jacobian(theta: np.ndarray) -> np.ndarray:
        base = cache.get(theta.tobytes())
        if base is None:
            base = residual(theta)
        J = np.zeros((base.size, theta.size))
        for c in range(theta.size):
            # relative to the value (a pump constant in m^3/(s V) is 7e-6), or to the
            # range of one that starts at 0 (an offset, a threshold)
            step = DIFF_STEP * (max(abs(theta[c]), 1e-3 * (hi_a[c] - lo_a[c])) if math.isfinite(hi_a[c])
                                else abs(theta[c]) or 1.0)
            t = theta.copy()
            t[c] = theta[c] + step if theta[c] + step <= hi_a[c] else theta[c] - step
            d = t[c] - theta[c]
            if c < nc + no:
                J[:, c] = (residual(t) - base) / d
            else:
                j = (c - nc - no) // n_states
                p, off = unpack(t)
                J[starts[j]:starts[j + 1], c] = (log_residual(p, off, j, t) - base[starts[j]:starts[j + 1]]) / d
        return J

    def cached_residual(theta: np.ndarray) -> np.ndarray:
        r = residual(theta)
        cache.clear()
        cache[theta.tobytes()] = r
        return r

    r0 = cached_residual(theta0)
    sol = least_squares(cached_residual, theta0, jac=jacobian, bounds=(lo_a, hi_a), method="trf",
                        x_scale="jac", xtol=TOLERANCE, ftol=TOLERANCE, gtol=TOLERANCE,
                        max_nfev=max_evaluations)
    if sol.status <= 0 or not np.all(np.isfinite(sol.fun)):
        raise IdentificationError(f"the fit did not converge ({sol.message.rstrip('.')}); "
                                  "free fewer constants or give better starting values (--par)")
    stderr = _standard_errors(sol.jac, sol.fun)
    loose = [n for n, e in zip(names, stderr) if not math.isfinite(e)]
    if loose:
        raise IdentificationError(f"the logs do not determine {', '.join(loose)} (the output does not depend "
                                  "on it there): free fewer constants or use logs in which the pumps move")
    if sol.cost > 0.5 * float(r0 @ r0) * (1 + 1e-9) + 1e-24 * r0.size:
        raise IdentificationError("the fit did not converge (it ended worse than it started); "
                                  "free fewer constants or give better starting values (--par)")
    fitted, off = unpack(sol.x)
    est = tuple(Estimate(n, float(sol.x[i]), float(stderr[i]), start_c[i]) for i, n in enumerate(names))
    offs = tuple(Estimate(f"y{outputs[j] + 1}{OFFSET_SUFFIX}", float(off[j]), float(stderr[nc + j]), 0.0)
                 for j in range(no))
    initial = tuple(tuple(float(v) for v in sol.x[nc + no + j * n_states:nc + no + (j + 1) * n_states])
                    for j in range(len(experiments)))
    predicted = tuple(predict(fitted, e, initial[j], off) for j, e in enumerate(experiments))
    rms = float(np.sqrt(np.mean(sol.fun ** 2)))
    return PhysicalFit(fitted, est, offs, initial, tuple(experiments), predicted, rms, calls[0])


def _standard_errors(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """sqrt(diag(s^2 (J^T J)^-1)); inf where J^T J is singular in that direction."""
    n, p = J.shape
    dof = max(n - p, 1)
    s2 = float(r @ r) / dof
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    tol = sv.max() * max(J.shape) * np.finfo(float).eps if sv.size else 0.0
    keep = sv > tol
    cov = (vt[keep].T / sv[keep] ** 2) @ vt[keep]
    out = np.sqrt(np.maximum(np.diag(cov) * s2, 0.0))
    null = vt[~keep]
    if null.size:
        out[np.any(np.abs(null) > 1e-6, axis=0)] = np.inf
    return out


# --- validation on another log --------------------------------------------------------------

#: Rows at the start of a validation log over which its initial levels are estimated.
INITIAL_ROWS = 20


def estimate_initial(plant: Plant, exp: Experiment, offsets: Sequence[float], rows: int = INITIAL_ROWS
                     ) -> tuple[float, ...]:
    """The levels at a log's first row that best explain its first `rows` readings
    with the constants held (least squares over the levels alone, from the measured
    tanks and the steady state of the first input for the others)."""
    n = min(max(rows, 2), exp.rows)
    part = Experiment(exp.name, exp.h, exp.u[:n], exp.y[:n], exp.outputs)
    x0 = np.array(initial_levels(plant, part, offsets, rows=1))
    lo = np.array([s.lo for s in plant.states])
    hi = np.array([s.hi for s in plant.states])

    def residual(x: np.ndarray) -> np.ndarray:
        return (predict(plant, part, x, offsets) - part.y).ravel()

    sol = least_squares(residual, np.clip(x0, lo, hi), bounds=(lo, hi), x_scale=hi - lo, max_nfev=50)
    return tuple(float(v) for v in sol.x)


def validate_physical(plant: Plant, exp: Experiment, offsets: Sequence[float],
                      rows: int = INITIAL_ROWS) -> tuple[list[Figure], np.ndarray, tuple[float, ...]]:
    """Simulate `exp`'s inputs from levels estimated on its first `rows` rows: the
    figures, the predicted sensor voltages and the initial levels used."""
    x0 = estimate_initial(plant, exp, offsets, rows)
    ym = predict(plant, exp, x0, offsets)
    fitted = PhysicalFit(plant, (), (), (x0,), (exp,), (ym,), 0.0, 0)
    return fitted.fits(), ym, x0
