"""Physical-parameter identification: fit the constants of the plant in use by
minimizing the simulation (output) error of its own nonlinear model over logs.

Each log is simulated open loop from its initial levels with the logged pump
voltages held over each sample, and the sensor voltages predicted, plus one offset
per sensor (on by default from the command line), are compared with the logged
ones.  The unknowns: the free constants (default :data:`DEFAULT_FREE`, plus those
of the real-rig effects asked for, :data:`PHYSICS`), the offsets, and the initial
level of every tank in every log (unmeasured tanks too).

A real rig's constants can be far from the preset's, so the fit does not trust its
start: it starts from the `.par`'s constants, from constants estimated from the logs
(core.identify.physical_starts) and from random ones spread around those, simulates
them all together (core.identify.fastsim: many parameter sets at once), refines the
best few by trust-region least squares (scipy's "trf", every parameter scaled to
its size), and polishes the best on the plant's own simulator (``advance``), whose
figures are the ones reported.  A fit stopped by its budget, by the user or by its
evaluation limit returns its best point and says so, with the constants that moved
most; it never ends in a bare error.

The uncertainty of each estimate is its standard error from the Jacobian at the
optimum, sqrt(diag(s^2 (J^T J)^-1)), s^2 = SSE / (N - p), with the correlation
matrix; the constants the logs leave open are named with the experiment that would
determine them, and pairs that trade off are listed.

A sensor gain and the flow constants cannot both be free on level data alone
(scaling the gain by c is undone by scaling the pump coefficients by c and the
outlets by sqrt(c)), which is why the gains are fixed by default: the lab
calibrates them against a ruler (Setup's calibration).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from quadtank_tui.core.identify import IdentificationError, fastsim
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
    their range: the change of the reading between a thousandth and two thousandths
    of each tank, where none saturates, so that an offset does not count)."""
    low = np.array([1e-3 * s.hi for s in plant.states])
    return (np.asarray(plant.output(tuple(2 * low)), dtype=float) - np.asarray(plant.output(tuple(low)), dtype=float)) / low


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
class StartResult:
    """One start of the multi-start: where it came from, its RMS there (V) and after
    its refinement (NaN: the coarse stage left it)."""

    label: str
    rms_start: float
    rms_end: float = math.nan


@dataclass(frozen=True)
class PhysicalFit:
    """The result: the plant with the fitted constants, each constant's estimate,
    sensor offsets (V), initial levels per log, per-log, per-output figures, and what
    the fit says of itself (converged or stopped at its budget, the identifiability
    of each constant, the starts tried)."""

    plant: Plant
    constants: tuple[Estimate, ...]
    offsets: tuple[Estimate, ...]
    initial: tuple[tuple[float, ...], ...]
    experiments: tuple[Experiment, ...] = field(repr=False)
    predicted: tuple[np.ndarray, ...] = field(repr=False)
    rms: float
    evaluations: int
    converged: bool = True
    message: str = "converged"
    #: correlation matrix of the estimates, in the order of :attr:`names`
    correlation: tuple[tuple[float, ...], ...] = ()
    #: (constant, the experiment that would determine it) for those the logs leave open
    undetermined: tuple[tuple[str, str], ...] = ()
    #: pairs of estimates that trade off (|correlation| >= :data:`TRADE_OFF`)
    tradeoffs: tuple[tuple[str, str, float], ...] = ()
    starts: tuple[StartResult, ...] = ()
    #: the constants that moved most from the start (relative change), largest first
    moved: tuple[tuple[str, float], ...] = ()
    notes: tuple[str, ...] = ()
    seconds: float = 0.0

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.constants) + tuple(e.name for e in self.offsets)

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
    if name.startswith("lam"):  # a laminar outflow term: none or some
        return 0.0, math.inf
    if name.startswith("area"):  # a tank's cross-section relative to another's
        return 0.02, 50.0
    if name.startswith("off"):
        return -FULL_SCALE_V, FULL_SCALE_V
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


#: |correlation| from which two estimates are said to trade off.
TRADE_OFF = 0.95
#: Random starts of the coarse global stage (all simulated in one batch), how far
#: they spread (a factor either way, log-uniform), how many of the best are refined.
RANDOM_STARTS = 64
SPREAD = 4.0
REFINED = 6
#: Solver evaluations of each refinement of a start (the best is then polished).
REFINE_EVALUATIONS = 12
#: Budget of a fit, s of this process's CPU time (on a shared machine the fit does
#: the work it would do on an idle one): at its end the fit returns its best point.
BUDGET_S = 90.0
cpu_clock = time.process_time

#: The constants each real-rig effect frees, by plant kind (those the plant has).
PHYSICS: dict[str, dict[str, tuple[str, ...]]] = {
    "laminar": {"quadtank": ("lam1", "lam2", "lam3", "lam4"), "desautel-qtp": ("lam1", "lam2", "lam3", "lam4"),
                "coupled-cascade": ("lam1", "lam2"), "coupled-tito": ()},
    "overflow": {"quadtank": ("spill3", "spill4"), "desautel-qtp": ("spill3", "spill4"),
                 "coupled-cascade": ("area1", "spill1"), "coupled-tito": ("spill1", "spill2")},
    "deadzone": {"quadtank": ("vmin1", "vmin2"), "desautel-qtp": ("vmin1", "vmin2"),
                 "coupled-cascade": ("vmin",), "coupled-tito": ("vmin1", "vmin2")},
}
PHYSICS_NAMES = ("laminar", "overflow", "deadzone", "saturation")

#: What would determine a constant the logs leave open, by the start of its name.
DETERMINED_BY = (
    ("lam", "steps at two or more levels far apart (the laminar term grows with h, Torricelli's with sqrt h)"),
    ("spill", "a run that fills the upper tank to its brim"),
    ("area", "a run that fills the upper tank to its brim (where it spills says its size)"),
    ("ysat", "a run that takes that sensor to the end of its range"),
    ("vmin", "steps of that pump down to low voltages (where it stops moving water)"),
    ("kc", "a ruler calibration of the sensor (Setup's calibration)"),
    ("Gd", "a ruler calibration of the sensor (Setup's calibration)"),
    ("gamma", "a step on each pump with every tank logged"),
    ("y", "a log that starts with the tanks empty or a ruler reading (the sensor's zero)"),
)


def physics_names(plant: Plant, physics: Sequence[str], outputs: Sequence[int]) -> tuple[str, ...]:
    """The constants the effects `physics` free for `plant` (those it has)."""
    known = plant.values()
    out: list[str] = []
    for name in physics:
        if name == "saturation":
            out += [f"ysat{o + 1}" for o in outputs]
        elif name in PHYSICS:
            out += list(PHYSICS[name].get(plant.kind, ()))
        else:
            raise IdentificationError(f"unknown physics {name!r} (known: {', '.join(PHYSICS_NAMES)})")
    return tuple(n for n in dict.fromkeys(out) if n in known)


def _hint(name: str) -> str:
    for prefix, text in DETERMINED_BY:
        if name.startswith(prefix):
            return text
    return "a log in which it changes the levels (steps on the pump that feeds that tank)"


class _Stop(Exception):
    """The fit's budget ran out or the user cancelled: keep the best point."""


class _Problem:
    """The parameter vector theta = constants, offsets, initial levels of each log,
    and its residuals (the batch simulator's, or the plant's own)."""

    def __init__(self, plant: Plant, experiments: Sequence[Experiment], names: Sequence[str], n_off: int,
                 progress: ProgressFn | None, deadline: float) -> None:
        self.plant, self.experiments, self.names = plant, tuple(experiments), tuple(names)
        self.outputs = experiments[0].outputs
        self.nc, self.no, self.ns = len(names), n_off, len(plant.states)
        self.p = self.nc + self.no + self.ns * len(experiments)
        self.fast = fastsim.supports(plant.kind)
        self.base = {k: float(v) for k, v in plant.values().items()}
        self.plant_offsets = n_off > 0 and all(f"off{o + 1}" in self.base for o in self.outputs)
        self.progress, self.deadline = progress, deadline
        self.evaluations = 0
        self.best: tuple[float, np.ndarray] | None = None
        self.y = [e.y.ravel() for e in experiments]

    # parameter vectors -> values of the batch simulator
    def values(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        v: dict[str, np.ndarray | float] = dict(self.base)
        for i, n in enumerate(self.names):
            v[n] = theta[:, i]
        for j, o in enumerate(self.outputs):
            v[f"off{o + 1}"] = theta[:, self.nc + j] if self.no else self.base.get(f"off{o + 1}", 0.0)
        return {k: np.broadcast_to(np.asarray(x, float), (theta.shape[0],)) for k, x in v.items()}

    def x0(self, theta: np.ndarray, j: int) -> np.ndarray:
        at = self.nc + self.no + j * self.ns
        return theta[:, at:at + self.ns]

    def batch_residuals(self, theta: np.ndarray, j: int) -> np.ndarray:
        """Residuals (P x rows*outputs) of log j for each row of theta."""
        e = self.experiments[j]
        b = fastsim.batch(self.plant.kind, self.values(theta), theta.shape[0])
        x = fastsim.simulate(b, self.x0(theta, j), e.u, e.h)
        y = fastsim.sensors(b, x)[:, :, list(e.outputs)]
        return y.transpose(1, 0, 2).reshape(theta.shape[0], -1) - self.y[j]

    def unpack(self, theta: np.ndarray) -> tuple[Plant, np.ndarray | None]:
        changes = {n: float(v) for n, v in zip(self.names, theta[:self.nc])}
        off = theta[self.nc:self.nc + self.no] if self.no else None
        if self.plant_offsets and off is not None:
            changes.update({f"off{o + 1}": float(v) for o, v in zip(self.outputs, off)})
            off = None
        try:
            return self.plant.with_values(**changes), off
        except PlantError as exc:
            raise IdentificationError(f"the fit left the physics: {exc}") from None

    def plant_residual(self, theta: np.ndarray) -> np.ndarray:
        """Residuals of every log by the plant's own simulator (a set of constants
        the plant refuses: large residuals, which turn the solver back)."""
        try:
            p, off = self.unpack(theta)
        except IdentificationError:
            return np.full(sum(y.size for y in self.y), 1e3)
        return np.concatenate([(predict(p, e, self.x0(theta[None, :], j)[0], off) - e.y).ravel()
                               for j, e in enumerate(self.experiments)])

    def residual(self, theta: np.ndarray) -> np.ndarray:
        if self.fast:
            r = np.concatenate([self.batch_residuals(theta[None, :], j)[0] for j in range(len(self.experiments))])
        else:
            r = self.plant_residual(theta)
        self.note(theta, r)
        return r

    def note(self, theta: np.ndarray, r: np.ndarray) -> None:
        """Count an evaluation, keep the best point, report progress, stop on demand."""
        self.evaluations += 1
        sse = float(r @ r) if np.all(np.isfinite(r)) else math.inf
        if self.best is None or sse < self.best[0]:
            self.best = (sse, theta.copy())
        if self.progress is not None and not self.progress(self.evaluations, math.sqrt(sse / max(r.size, 1))):
            raise _Stop("cancelled")
        if cpu_clock() > self.deadline:
            raise _Stop("budget")

    def steps(self, theta: np.ndarray, scale: np.ndarray, hi: np.ndarray) -> np.ndarray:
        step = DIFF_STEP * np.maximum(np.abs(theta), scale)
        return np.where(theta + step <= hi, step, -step)

    def jacobian(self, theta: np.ndarray, scale: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Forward differences, the perturbed sets of each log simulated together (a
        log's initial levels move only that log)."""
        d = self.steps(theta, scale, hi)
        blocks = []
        shared = list(range(self.nc + self.no))
        for j in range(len(self.experiments)):
            at = self.nc + self.no + j * self.ns
            cols = shared + list(range(at, at + self.ns))
            th = np.repeat(theta[None, :], len(cols) + 1, axis=0)
            th[np.arange(1, len(cols) + 1), cols] += d[cols]
            if self.fast:
                r = self.batch_residuals(th, j)
            else:
                r = np.array([self.plant_residual_log(t, j) for t in th])
            J = np.zeros((r.shape[1], self.p))
            J[:, cols] = ((r[1:] - r[0]) / d[cols][:, None]).T
            blocks.append(J)
            if j == 0:
                base = [r[0]]
            else:
                base.append(r[0])
        self.note(theta, np.concatenate(base))
        return np.vstack(blocks)

    def plant_residual_log(self, theta: np.ndarray, j: int) -> np.ndarray:
        e = self.experiments[j]
        try:
            p, off = self.unpack(theta)
        except IdentificationError:
            return np.full(e.y.size, 1e3)
        return (predict(p, e, self.x0(theta[None, :], j)[0], off) - e.y).ravel()


def fit_physical(plant: Plant, experiments: Sequence[Experiment], free: Sequence[str] | None = None, *,
                 offsets: bool = False, progress: ProgressFn | None = None,
                 max_evaluations: int = MAX_EVALUATIONS, physics: Sequence[str] = (),
                 random_starts: int = RANDOM_STARTS, budget_s: float = BUDGET_S, seed: int = 0,
                 starts: Sequence[tuple[str, Mapping[str, float]]] = ()) -> PhysicalFit:
    """Fit `free` constants of `plant` (default :data:`DEFAULT_FREE`, plus those the
    effects `physics` free) to the logs.

    Starts: the plant's constants, starts estimated from the logs (steady levels,
    a linear fit's time constants mapped to the physical constants), and
    `random_starts` spread around them; all are simulated together, the best
    :data:`REFINED` refined, the best of those polished.  `progress(evaluations,
    rms)` is called after each simulation of all logs; it returns False to cancel.
    A fit stopped (cancelled, at its budget or at `max_evaluations`) returns its
    best point with converged False and says why.  `starts` adds starts of one's
    own: (label, {constant: value}), the others at the `.par`'s.
    """
    t0, c0 = time.monotonic(), cpu_clock()
    if not experiments:
        raise IdentificationError("no log to fit")
    if len(set(tuple(e.outputs) for e in experiments)) != 1:
        raise IdentificationError("every log must hold the same outputs")
    base_names = tuple(free) if free is not None else DEFAULT_FREE.get(plant.kind, ())
    outputs = experiments[0].outputs
    names = tuple(dict.fromkeys(base_names + physics_names(plant, physics, outputs)))
    if not names and not offsets:
        raise IdentificationError("nothing to fit: name the constants to free")
    _check_free(plant, names)
    notes: list[str] = []
    plant = _fit_sensor_scale(plant, experiments, names, notes)
    missing = [n for n in physics if n in PHYSICS and not physics_names(plant, (n,), outputs)]
    if missing:
        notes.append(f"a {plant.kind} has no constants for {', '.join(missing)}: left out")
    n_off = len(outputs) if offsets else 0
    prob = _Problem(plant, experiments, names, n_off, progress, c0 + budget_s)
    lo, hi = _bounds(prob)
    scale = _scales(prob, lo, hi)
    rng = np.random.default_rng(seed)
    floor = max(noise_floor(experiments), LOG_RESOLUTION_V / math.sqrt(12.0))  # a log's digits are noise too
    labels, thetas = _starts(prob, rng, random_starts if prob.fast else 0, lo, hi, starts)
    results: list[StartResult] = []
    stopped = ""
    try:
        rms0 = _coarse(prob, thetas)
    except _Stop as why:
        stopped = str(why)
        rms0 = np.full(len(thetas), math.nan)
    order = [int(i) for i in np.argsort(np.where(np.isfinite(rms0), rms0, np.inf))]
    if starts:  # the best of one's own starts is refined whatever its rank
        own = range(len(labels) - random_starts - len(starts), len(labels) - random_starts) if prob.fast else ()
        best_own = min(own, key=lambda i: rms0[i] if np.isfinite(rms0[i]) else np.inf, default=None)
        if best_own is not None and best_own not in order[:REFINED - 1]:
            order.remove(best_own)
            order.insert(REFINED - 1, best_own)
    refined: list[tuple[float, np.ndarray, int, int]] = []
    if not stopped:
        for i in order[:REFINED]:
            try:
                sol = _solve(prob, thetas[i], lo, hi, scale,
                             min(REFINE_EVALUATIONS, max_evaluations) if len(order) > 1 else max_evaluations)
            except _Stop as why:
                stopped = str(why)
                break
            refined.append((2 * sol.cost, sol.x * scale, i, sol.status))
            results.append(StartResult(labels[i], float(rms0[i]), _rms(2 * sol.cost, prob)))
            if _rms(2 * sol.cost, prob) <= NOISE_MARGIN * floor:
                break  # at the noise of the readings: no other start can do better
    for i in order[len(refined):]:
        results.append(StartResult(labels[i], float(rms0[i])))
    sol_status = 0
    if refined:
        refined.sort(key=lambda t: t[0])
        sol_status = refined[0][3]
        if not stopped and sol_status <= 0 and len(order) > 1:
            try:
                sol = _solve(prob, refined[0][1], lo, hi, scale, max_evaluations)
                sol_status = sol.status
            except _Stop as why:
                stopped = str(why)
    if prob.best is None:
        raise IdentificationError("cancelled" if stopped == "cancelled" else "the fit ran out of time "
                                  "before one simulation of the logs")
    theta = prob.best[1]
    if not stopped and sol_status > 0 and prob.fast:
        theta = _polish(prob, theta, lo, hi, scale, c0 + budget_s)
    converged = not stopped and sol_status > 0
    message = ("converged" if converged else
               "cancelled: the best point so far" if stopped == "cancelled" else
               f"stopped at its budget ({budget_s:g} s): the best point so far" if stopped == "budget" else
               f"stopped after {max_evaluations} evaluations without converging: the best point so far")
    return _result(prob, theta, lo, hi, scale, thetas[0], results, converged, message,
                   notes, time.monotonic() - t0)


#: A refined start within this factor of the readings' noise ends the multi-start.
NOISE_MARGIN = 1.5


def noise_floor(experiments: Sequence[Experiment]) -> float:
    """The RMS of the readings' noise, V: from their second differences (white noise
    of s.d. s gives s sqrt(6) there; a slow level's curvature adds little), robustly
    (the median absolute deviation, so the steps of the inputs do not count)."""
    parts = []
    for e in experiments:
        d2 = np.diff(e.y, n=2, axis=0)
        if d2.shape[0] < 5:
            continue
        mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
        parts.append((1.4826 * mad / math.sqrt(6.0)) ** 2)
    return float(math.sqrt(np.mean(np.concatenate(parts)))) if parts else 0.0


#: A sensor whose highest reading lies above this multiple of its full tank's reading is
#: rescaled so that it lies at :data:`RESCALED_TOP` (the gain is not fitted).
SCALE_LIMIT = 1.02
RESCALED_TOP = 0.7


def _fit_sensor_scale(plant: Plant, experiments: Sequence[Experiment], names: Sequence[str],
                      notes: list[str]) -> Plant:
    """The plant with its sensor gains raised where the readings go higher than a full
    tank would read: another rig's sensor scale (a gain and the flow constants trade
    off exactly, so any gain that keeps the readings inside the tank will do; the
    flows follow it)."""
    gains = SENSOR_GAINS.get(plant.kind, ())
    if not gains or any(g in names for g in gains):
        return plant
    outputs = experiments[0].outputs
    top = {o: max(float(e.y[:, j].max()) for e in experiments) for j, o in enumerate(outputs)}
    full = sensor_gains(plant) * np.array([s.hi for s in plant.states])
    changes: dict[str, float] = {}
    values = plant.values()
    for o, t in top.items():
        if t > SCALE_LIMIT * full[o]:
            name = gains[o] if len(gains) > 1 else gains[0]
            new = t / (RESCALED_TOP * plant.states[o].hi)
            changes[name] = max(changes.get(name, 0.0), new)
    if not changes:
        return plant
    for name, new in changes.items():
        notes.append(f"{name} {values[name]:.6g} -> {new:.6g}: the readings go above what a full tank reads "
                     "with the .par's sensor gain (another rig's scale; the flow constants follow it)")
    return plant.with_values(**changes)


def _rms(sse: float, prob: _Problem) -> float:
    return math.sqrt(sse / max(sum(y.size for y in prob.y), 1))


def _bounds(prob: _Problem) -> tuple[np.ndarray, np.ndarray]:
    plant = prob.plant
    lo = [bounds_of(plant, n)[0] for n in prob.names] + [-FULL_SCALE_V] * prob.no
    hi = [bounds_of(plant, n)[1] for n in prob.names] + [FULL_SCALE_V] * prob.no
    for _ in prob.experiments:
        lo += [s.lo for s in plant.states]
        hi += [s.hi for s in plant.states]
    return np.array(lo, float), np.array(hi, float)


def _scales(prob: _Problem, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Each parameter's size (the solver works on theta / scale)."""
    out = np.ones(prob.p)
    for i, n in enumerate(prob.names):
        v = abs(prob.base[n])
        if n.startswith("lam"):
            v = max(v, _typical_laminar(prob, n))
        if n.startswith("area"):
            v = max(v, 1.0)
        out[i] = v if v > 0 else (0.1 * (hi[i] - lo[i]) if math.isfinite(hi[i] - lo[i]) else 1.0)
    out[prob.nc:prob.nc + prob.no] = 0.1
    for j in range(len(prob.experiments)):
        at = prob.nc + prob.no + j * prob.ns
        out[at:at + prob.ns] = [0.1 * s.hi for s in prob.plant.states]
    return out


def _typical_laminar(prob: _Problem, name: str) -> float:
    """A laminar coefficient that carries a tenth of the outlet's flow at half height."""
    i = int(name[3:]) - 1
    outlet = prob.plant.outlet_names[i] if i < len(prob.plant.outlet_names) else ""
    coef = prob.base.get(outlet, 0.0)
    half = 0.5 * prob.plant.states[i].hi
    return 0.1 * coef * math.sqrt(2.0 * prob.plant.gravity * half) / half


def _full_theta(prob: _Problem, consts: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                offsets: Sequence[float] | None = None) -> np.ndarray:
    """A start's whole parameter vector: offsets 0 (or those given), the measured
    tanks' levels from the first readings, the others at the steady state of the
    first input."""
    theta = np.zeros(prob.p)
    theta[:prob.nc] = consts
    if offsets is not None and prob.no:
        theta[prob.nc:prob.nc + prob.no] = offsets
    one = theta[None, :]
    for j, e in enumerate(prob.experiments):
        at = prob.nc + prob.no + j * prob.ns
        if prob.fast:
            b = fastsim.batch(prob.plant.kind, prob.values(one), 1)
            x = fastsim.steady(b, e.u[0])[0]
            gains = b.gain[0]
            offs = b.offset[0]
        else:
            p, _ = prob.unpack(theta)
            x = np.array(initial_levels(p, e))
            gains, offs = sensor_gains(p), np.zeros(prob.ns)
        first = e.y[:3].mean(axis=0)
        for k, o in enumerate(e.outputs):
            x[o] = (first[k] - offs[o]) / gains[o]
        theta[at:at + prob.ns] = x
    inside = lo + 1e-9 * np.maximum(np.abs(lo), 1e-12)
    with np.errstate(invalid="ignore"):
        top = np.where(np.isfinite(hi), hi - 1e-9 * np.maximum(np.abs(hi), 1e-12), hi)
    return np.clip(theta, inside, top)


def _starts(prob: _Problem, rng: np.random.Generator, n_random: int, lo: np.ndarray, hi: np.ndarray,
            own: Sequence[tuple[str, Mapping[str, float]]] = ()) -> tuple[list[str], np.ndarray]:
    """The starts: the plant's constants, those estimated from the logs, and random
    ones spread around the latter in turn (log-uniform within a factor
    :data:`SPREAD`, fractions uniform, a cross-section ratio within 0.1..10)."""
    from quadtank_tui.core.identify.physical_starts import data_starts

    nc = prob.nc
    par = np.array([prob.base[n] for n in prob.names])
    par = np.where([n.startswith("lam") and v == 0 for n, v in zip(prob.names, par)],
                   [_typical_laminar(prob, n) if n.startswith("lam") else 0.0 for n in prob.names], par)
    for i, n in enumerate(prob.names):
        if n.startswith("ysat") and par[i] == 0.0:
            par[i] = _start(prob.plant, n, prob.experiments)
        if n.startswith("area") and par[i] == 0.0:  # off: the same cross-section as the tank below
            par[i] = 1.0
    labels, consts = ["the .par's constants"], [par]
    for label, c in data_starts(prob.plant, prob.experiments, prob.names, par):
        labels.append(label)
        consts.append(c)
    offsets = {len(consts) + k: [float(given.get(f"off{o + 1}", 0.0)) for o in prob.outputs]
               for k, (_, given) in enumerate(own)}
    for label, given in own:
        labels.append(label)
        consts.append(np.array([float(given.get(n, v)) for n, v in zip(prob.names, par)]))
    centres = consts[1:] or consts
    for k in range(n_random):
        centre = centres[k % len(centres)]
        c = centre.copy()
        for i, n in enumerate(prob.names):
            if n.startswith(("gamma", "spill")):
                c[i] = rng.uniform(0.05, 0.95)
            elif n.startswith("vmin"):
                c[i] = rng.uniform(0.0, 0.2) * min(s.hi for s in prob.plant.inputs)
            elif n.startswith("ysat"):
                c[i] = centre[i]
            elif n.startswith("area"):
                c[i] = math.exp(rng.uniform(math.log(0.1), math.log(10.0)))
            elif n.startswith("lam"):
                c[i] = centre[i] * math.exp(rng.uniform(-2.0, 2.0))
            elif c[i] > 0:
                c[i] = c[i] * math.exp(rng.uniform(-math.log(SPREAD), math.log(SPREAD)))
        labels.append(f"random {k + 1}")
        consts.append(c)
    thetas = np.array([_full_theta(prob, np.clip(c, lo[:nc], hi[:nc]), lo, hi, offsets.get(k))
                       for k, c in enumerate(consts)])
    if prob.fast:
        thetas = _unmeasured_levels(prob, thetas, lo, hi)
    return labels, thetas


#: Levels tried for the tanks a log does not measure, at each start: the steady
#: state of the first input scaled by these factors, and these shares of the brim.
LEVEL_FACTORS = (1.0, 0.25, 0.5, 2.0, 4.0)
LEVEL_SHARES = (0.05, 0.15, 0.3, 0.5, 0.7, 0.9, 1.0)


def _unmeasured_levels(prob: _Problem, thetas: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Each start's initial levels of the unmeasured tanks: of those tried, the one
    that best explains the first quarter of each log (a log need not start at rest,
    and a wrong unmeasured level leads the fit astray)."""
    out = thetas.copy()
    for j, e in enumerate(prob.experiments):
        hidden = [i for i in range(prob.ns) if i not in e.outputs]
        if not hidden:
            continue
        at = prob.nc + prob.no + j * prob.ns
        tops = np.array([prob.plant.states[i].hi for i in hidden])
        cands = []
        for f in LEVEL_FACTORS:
            c = thetas.copy()
            c[:, [at + i for i in hidden]] = np.minimum(thetas[:, [at + i for i in hidden]] * f, tops)
            cands.append(c)
        for share in LEVEL_SHARES:
            c = thetas.copy()
            c[:, [at + i for i in hidden]] = share * tops
            cands.append(c)
        stack = np.clip(np.concatenate(cands), lo, hi)
        rows = max(10, e.rows // 4)
        part = Experiment(e.name, e.h, e.u[:rows], e.y[:rows], e.outputs)
        sub = _Problem(prob.plant, [part], prob.names, prob.no, None, math.inf)
        cols = list(range(prob.nc + prob.no)) + [at + i for i in range(prob.ns)]
        r = sub.batch_residuals(stack[:, cols], 0)
        sse = np.einsum("ij,ij->i", r, r).reshape(len(cands), len(thetas))
        best = np.nanargmin(np.where(np.isfinite(sse), sse, np.inf), axis=0)
        out[:, at:at + prob.ns] = stack.reshape(len(cands), len(thetas), -1)[best, np.arange(len(thetas)), at:at + prob.ns]
    return out


def _coarse(prob: _Problem, thetas: np.ndarray) -> np.ndarray:
    """RMS of every start, all simulated together (one run of each log)."""
    if prob.fast:
        sse = np.zeros(len(thetas))
        for j in range(len(prob.experiments)):
            r = prob.batch_residuals(thetas, j)
            sse += np.einsum("ij,ij->i", r, r)
        for t, s in zip(thetas, sse):
            prob.evaluations += 1
            if np.isfinite(s) and (prob.best is None or s < prob.best[0]):
                prob.best = (float(s), t.copy())
        if prob.progress is not None and not prob.progress(prob.evaluations, _rms(float(np.nanmin(sse)), prob)):
            raise _Stop("cancelled")
    else:
        sse = np.array([float(r @ r) for r in (prob.residual(t) for t in thetas)])
    return np.sqrt(sse / max(sum(y.size for y in prob.y), 1))


def _solve(prob: _Problem, theta0: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: np.ndarray,
           max_nfev: int) -> Any:
    """Trust-region least squares on theta / scale from theta0."""
    cache: dict[bytes, np.ndarray] = {}

    def fun(z: np.ndarray) -> np.ndarray:
        return prob.residual(z * scale)

    def jac(z: np.ndarray) -> np.ndarray:
        return prob.jacobian(z * scale, scale, hi) * scale

    z0 = theta0 / scale
    z0 = np.clip(z0, lo / scale, hi / scale)
    del cache
    return least_squares(fun, z0, jac=jac, bounds=(lo / scale, hi / scale), method="trf", x_scale=1.0,
                         xtol=TOLERANCE, ftol=TOLERANCE, gtol=TOLERANCE, max_nfev=max_nfev)


#: Plant-simulator evaluations the polish may use (each is one run of every log by
#: the plant's own adaptive step).
POLISH_EVALUATIONS = 6


def _polish(prob: _Problem, theta: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: np.ndarray,
            deadline: float) -> np.ndarray:
    """The batch simulator's optimum moved to the plant's own: a few solver steps on
    the plant's residuals with the batch Jacobian, kept only if better."""
    t = cpu_clock()
    r0 = prob.plant_residual(theta)
    cost = cpu_clock() - t
    fast = prob.residual(theta)
    sse0 = float(r0 @ r0)
    if sse0 <= float(fast @ fast) * 1.001 + 1e-30 or cpu_clock() + 3 * cost > deadline:
        return theta
    best_sse, best = [sse0], [theta]

    def fun(z: np.ndarray) -> np.ndarray:
        if cpu_clock() + cost > deadline:
            raise _Stop("budget")
        r = prob.plant_residual(z * scale)
        if float(r @ r) < best_sse[0]:
            best_sse[0], best[0] = float(r @ r), z * scale
        return r

    try:
        least_squares(fun, theta / scale, jac=lambda z: prob.jacobian(z * scale, scale, hi) * scale,
                      bounds=(lo / scale, hi / scale), method="trf", x_scale=1.0, xtol=TOLERANCE, ftol=TOLERANCE,
                      gtol=TOLERANCE, max_nfev=POLISH_EVALUATIONS)
    except _Stop:
        pass
    return best[0]


def _result(prob: _Problem, theta: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: np.ndarray,
            start: np.ndarray, starts: list[StartResult], converged: bool, message: str, notes: list[str],
            seconds: float) -> PhysicalFit:
    nc, no = prob.nc, prob.no
    fitted, off = prob.unpack(theta)
    saved_deadline = prob.deadline
    prob.deadline, prob.progress = math.inf, None
    J = prob.jacobian(theta, scale, hi) if prob.fast else _plant_jacobian(prob, theta, scale, hi)
    prob.deadline = saved_deadline
    predicted = tuple(predict(fitted, e, prob.x0(theta[None, :], j)[0], off) for j, e in enumerate(prob.experiments))
    r = np.concatenate([(ym - e.y).ravel() for ym, e in zip(predicted, prob.experiments)])
    stderr, corr = _covariance(J * scale, r, scale)
    outputs = prob.outputs
    est = tuple(Estimate(n, float(theta[i]), float(stderr[i]), float(start[i])) for i, n in enumerate(prob.names))
    offs = tuple(Estimate(f"y{outputs[j] + 1}{OFFSET_SUFFIX}", float(theta[nc + j]), float(stderr[nc + j]),
                          float(start[nc + j])) for j in range(no))
    names = [e.name for e in est] + [e.name for e in offs]
    k = nc + no
    c = corr[:k, :k]
    undetermined = tuple((n, _hint(n)) for i, n in enumerate(names)
                         if not math.isfinite(stderr[i]) or stderr[i] > max(abs(theta[i]), 1e-12 if i >= nc else 0.0)
                         and not (i >= nc and stderr[i] < 0.05))
    tradeoffs = tuple((names[a], names[b], float(c[a, b])) for a in range(k) for b in range(a + 1, k)
                      if np.isfinite(c[a, b]) and abs(c[a, b]) >= TRADE_OFF)
    rel = [(n, float((theta[i] - start[i]) / max(abs(start[i]), scale[i]))) for i, n in enumerate(prob.names)]
    moved = tuple(sorted(rel, key=lambda t: -abs(t[1]))[:3])
    initial = tuple(tuple(float(v) for v in prob.x0(theta[None, :], j)[0]) for j in range(len(prob.experiments)))
    rms = float(np.sqrt(np.mean(r * r)))
    return PhysicalFit(fitted, est, offs, initial, prob.experiments, predicted, rms, prob.evaluations, converged,
                       message, tuple(tuple(float(v) for v in row) for row in c), undetermined, tradeoffs,
                       tuple(starts), moved, tuple(notes), seconds)


def _plant_jacobian(prob: _Problem, theta: np.ndarray, scale: np.ndarray, hi: np.ndarray) -> np.ndarray:
    base = prob.plant_residual(theta)
    d = prob.steps(theta, scale, hi)
    J = np.zeros((base.size, prob.p))
    for i in range(prob.p):
        t = theta.copy()
        t[i] += d[i]
        J[:, i] = (prob.plant_residual(t) - base) / d[i]
    return J


def _covariance(Js: np.ndarray, r: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Standard errors sqrt(diag(s^2 (J^T J)^-1)) (inf along the directions the data
    leave open) and the correlation matrix, from the Jacobian on theta / scale."""
    n, p = Js.shape
    s2 = float(r @ r) / max(n - p, 1)
    _, sv, vt = np.linalg.svd(Js, full_matrices=False)
    tol = sv.max() * max(Js.shape) * np.finfo(float).eps * 1e3 if sv.size else 0.0
    keep = sv > tol
    cov = (vt[keep].T / sv[keep] ** 2) @ vt[keep] * s2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    null = vt[~keep]
    sd = sd * scale
    if null.size:
        loose = np.any(np.abs(null) > 1e-6, axis=0)
        sd[loose] = np.inf
        corr[loose, :] = np.nan
        corr[:, loose] = np.nan
    return sd, corr


# --- validation on another log --------------------------------------------------------------

#: Rows at the start of a validation log over which its initial levels are estimated.
INITIAL_ROWS = 20


#: V: a log's resolution (six decimals of the normalized reading, 10 V full scale)
LOG_RESOLUTION_V = 1e-5


def estimate_initial(plant: Plant, exp: Experiment, offsets: Sequence[float], rows: int = INITIAL_ROWS
                     ) -> tuple[float, ...]:
    """The levels at a log's first row that best explain its first `rows` readings
    with the constants held (least squares over the levels, from the measured
    tanks and the steady state of the first input for the others).

    A measured tank's first reading is where it was up to its sensor's noise, so
    it moves at most three times that noise (from its first readings' third
    differences) from it, and not at all in a log as clean as its printed digits;
    an unmeasured tank, and one whose first reading does not invert to its level
    (a saturated sensor, an offset inside the plant), is free.  Without that bound the least squares moved the
    start to make up for a plant that does not fit the log (another .par's)."""
    n = min(max(rows, 2), exp.rows)
    part = Experiment(exp.name, exp.h, exp.u[:n], exp.y[:n], exp.outputs)
    x0 = np.array(initial_levels(plant, part, offsets, rows=1))
    lo = np.array([s.lo for s in plant.states])
    hi = np.array([s.hi for s in plant.states])
    x0 = np.clip(x0, lo, hi)
    gains = sensor_gains(plant)
    # third differences: the levels' own curvature cancels, white noise stays (its variance times 20)
    noise = (np.std(np.diff(part.y, n=3, axis=0), axis=0) / np.sqrt(20.0) if n >= 5
             else np.zeros(len(exp.outputs)))
    first = predict(plant, Experiment(exp.name, exp.h, exp.u[:1], exp.y[:1], exp.outputs), x0, offsets)[0]
    free = np.ones(len(x0), dtype=bool)
    for j, o in enumerate(exp.outputs):
        band = 3.0 * float(noise[j])
        if abs(first[j] - part.y[0, j]) > max(band, LOG_RESOLUTION_V) or gains[o] == 0:
            continue  # the reading does not invert to its level (a saturated sensor, the plant's own offset): free
        if noise[j] <= LOG_RESOLUTION_V / 2:  # no noise but the printed digits' rounding
            free[o] = False
        else:
            lo[o] = max(lo[o], x0[o] - band / abs(gains[o]))
            hi[o] = min(hi[o], x0[o] + band / abs(gains[o]))
    if not free.any() or np.any(hi[free] <= lo[free]):
        return tuple(float(v) for v in x0)

    def residual(z: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[free] = z
        return (predict(plant, part, x, offsets) - part.y).ravel()

    sol = least_squares(residual, np.clip(x0[free], lo[free], hi[free]), bounds=(lo[free], hi[free]),
                        x_scale=hi[free] - lo[free], max_nfev=50)
    out = x0.copy()
    out[free] = sol.x
    return tuple(float(v) for v in out)


def validate_physical(plant: Plant, exp: Experiment, offsets: Sequence[float],
                      rows: int = INITIAL_ROWS) -> tuple[list[Figure], np.ndarray, tuple[float, ...]]:
    """Simulate `exp`'s inputs from levels estimated on its first `rows` rows: the
    figures, the predicted sensor voltages and the initial levels used."""
    x0 = estimate_initial(plant, exp, offsets, rows)
    ym = predict(plant, exp, x0, offsets)
    fitted = PhysicalFit(plant, (), (), (x0,), (exp,), (ym,), 0.0, 0)
    return fitted.fits(), ym, x0
