"""Throughput: our engine against python-control on the same closed loop.

    .venv/bin/python benchmarks/throughput.py [--batch 1000] [--pc-batch 3] [--repeat 3]

The experiment (benchmarks/experiment.py): P-, decentralized PI (3.0, 30) and
(2.7, 40), PRBS references, 3600 samples at 1 s.

python-control side: the nonlinear plant is a continuous `control.nlsys` and the PI
pair a discrete-time `control.nlsys` (dt = 1).  python-control cannot interconnect
systems of different timebases ("Systems have incompatible timebases"), so the
sampled-data loop is closed the way its documentation leaves it to the user: each
sample, the discrete controller's `output`/`dynamics` give u and the next state, and
`input_output_response` integrates the plant over the sample with u held (solve_ivp,
rtol 1e-8, atol 1e-10: accurate enough to compare against to 1e-3).

Single: each side runs `--repeat` times, in turns, and the medians are compared
(one run of ours lasts 60-90 ms, a spot of a shared machine's speed; one of
python-control's 2-3 s); each turn's own ratio is printed too.

Batch: ours runs all experiments at once on the vectorized path (core/batch.py);
python-control runs `--pc-batch` of them one after the other, and its time for the
whole batch is that, scaled (running 1000 would take hours).  Figures are printed,
not asserted; this is not a test.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import time
from pathlib import Path
from typing import Callable, TypeVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import control  # noqa: E402

from benchmarks.experiment import H0, PI, PLANT, U0, references, run_engine  # noqa: E402
from quadtank_tui.core.batch import pi_batch  # noqa: E402
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import rhs  # noqa: E402

SAMPLES = 3600
H = 1.0
T = TypeVar("T")


def python_control_systems() -> tuple[control.NonlinearIOSystem, control.NonlinearIOSystem]:
    p = PLANT

    def plant_update(t, x, u, params):
        return np.array(rhs(x, u, p))

    def plant_output(t, x, u, params):
        return p.kc * np.asarray(x) / FULL_SCALE_V

    plant = control.nlsys(plant_update, plant_output, states=4, inputs=2, outputs=4, name="plant")
    K = np.array([PI[0].K, PI[1].K])
    gi = np.array([PI[0].K * H / PI[0].Ti, PI[1].K * H / PI[1].Ti])
    tr = np.array([H / PI[0].Tr, H / PI[1].Tr])

    def ctrl_v(x, u):
        return K * (u[:2] - u[2:]) + x   # u = (r1, r2, y1, y2), b = 1

    def ctrl_update(t, x, u, params):
        v = ctrl_v(x, u)
        return x + gi * (u[:2] - u[2:]) + tr * (np.clip(v, 0.0, 1.0) - v)

    def ctrl_output(t, x, u, params):
        return np.clip(ctrl_v(x, u), 0.0, 1.0)

    pi = control.nlsys(ctrl_update, ctrl_output, states=2, inputs=4, outputs=2, dt=H, name="pi")
    return plant, pi


def run_python_control(refs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, 4) y and (K, 2) u of the sampled loop in python-control."""
    plant, pi = python_control_systems()
    x = np.array(H0, dtype=float)
    xc = np.array(U0, dtype=float)        # integrators holding u0 at r = y (tracking)
    ys, us = np.empty((len(refs), 4)), np.empty((len(refs), 2))
    for k, r in enumerate(refs):
        y = plant.output(0.0, x, np.zeros(2))
        cu = np.concatenate([r, y[:2]])
        u = pi.output(k * H, xc, cu)
        xc = pi.dynamics(k * H, xc, cu)
        ys[k], us[k] = y, u
        resp = control.input_output_response(
            plant, [0.0, H], np.tile(FULL_SCALE_V * u, (2, 1)).T, x,
            solve_ivp_kwargs={"rtol": 1e-8, "atol": 1e-10},
        )
        x = resp.states[:, -1]
    return ys, us


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=int, default=1000, help="experiments in the batch (default 1000)")
    ap.add_argument("--pc-batch", type=int, default=3, help="python-control runs timed for the batch estimate")
    ap.add_argument("--repeat", type=int, default=3, help="single runs of each, in turns (default 3)")
    args = ap.parse_args()

    print(f"experiment: P-, decentralized PI (3.0, 30) (2.7, 40), PRBS references, {SAMPLES} samples at {H:g} s")
    print(f"load average {os.getloadavg()[0]:.1f}; times are CPU (process_time), wall in brackets; "
          "the ratios are of CPU times (a shared machine's other programs inflate wall time unevenly)")
    # In turns, `--repeat` times: one run of ours is 60-90 ms, a spot of the machine's
    # speed, python-control's 2-3 s an average of it; the medians are compared.  Each
    # run starts on a collected heap, ours warmed again by a short run: right after
    # python-control's, ours took 15-25 % longer once (its garbage, the caches), and
    # the next run not.  (The first warm-up also takes the imports and first calls.)
    ours, theirs = [], []
    for _ in range(args.repeat):
        gc.collect()
        run_engine(seed=1, samples=100)
        hist, t_ours = timed(lambda: run_engine(seed=1, samples=SAMPLES))
        refs = references(hist)
        gc.collect()
        (y_pc, u_pc), t_pc = timed(lambda: run_python_control(refs))
        ours.append(t_ours)
        theirs.append(t_pc)
    c_ours, w_ours = _median(ours)
    c_pc, w_pc = _median(theirs)
    y_ours = np.stack([hist[f"y{j}"] for j in (1, 2, 3, 4)], axis=1)
    u_ours = np.stack([hist["u1"], hist["u2"]], axis=1)
    dy = float(np.max(np.abs(y_ours - y_pc)))
    du = float(np.max(np.abs(u_ours - u_pc)))
    print(f"single   engine         {c_ours:8.3f} s  ({w_ours:.3f} s)  {1e6 * c_ours / SAMPLES:6.1f} us a sample")
    print(f"single   python-control {c_pc:8.3f} s  ({w_pc:.3f} s)  {1e6 * c_pc / SAMPLES:6.1f} us a sample")
    print(f"single   ratio          {c_pc / c_ours:8.1f} x  (wall {w_pc / w_ours:.1f} x; target >= 30 x)"
          f"  the medians of {args.repeat} runs each, in turns; each turn's: "
          + ", ".join(f"{p[0] / o[0]:.1f}" for o, p in zip(ours, theirs)))
    print(f"single   max |y diff|   {dy:.2e}   max |u diff| {du:.2e}  (normalized; must be < 1e-3)")

    # The batch: different seeds give different PRBS references.
    seeds = range(1, args.batch + 1)
    all_refs, (t_refs, w_refs) = timed(lambda: np.stack([_prbs_refs(s) for s in seeds]))
    run, (t_batch, w_batch) = timed(lambda: pi_batch(PLANT, H0, U0, all_refs, PI, H))
    dyb = float(np.max(np.abs(run.y[0] - y_ours)))

    _, (c_pcs, w_pcs) = timed(lambda: [run_python_control(all_refs[s - 1]) for s in list(seeds)[: args.pc_batch]])
    t_pc_each, w_pc_each = c_pcs / args.pc_batch, w_pcs / args.pc_batch
    t_pc_batch = t_pc_each * args.batch
    ours_total = t_batch + t_refs
    print(f"batch    {args.batch} experiments, vectorized numpy path (core/batch.py)")
    print(f"batch    ours           {ours_total:8.3f} s  ({w_refs + w_batch:.3f} s; {t_refs:.3f} s PRBS references "
          f"+ {t_batch:.3f} s loops)  {1e6 * ours_total / (args.batch * SAMPLES):.2f} us a sample")
    print(f"batch    python-control {t_pc_batch:8.1f} s  (estimated: {args.pc_batch} runs timed, "
          f"{t_pc_each:.3f} s each ({w_pc_each:.3f} s), x {args.batch})")
    print(f"batch    ratio          {t_pc_batch / ours_total:8.1f} x  (wall "
          f"{w_pc_each * args.batch / (w_refs + w_batch):.1f} x; target >= 500 x)")
    print(f"batch    max |y diff| of experiment 1 against the engine: {dyb:.2e}")


def timed(fn: Callable[[], T]) -> tuple[T, tuple[float, float]]:
    """fn()'s value, and the CPU (time.process_time) and wall seconds it took."""
    c0, w0 = time.process_time(), time.perf_counter()
    value = fn()
    return value, (time.process_time() - c0, time.perf_counter() - w0)


def _median(times: list[tuple[float, float]]) -> tuple[float, float]:
    """The median CPU time and the median wall time of runs timed by :func:`timed`."""
    return float(np.median([c for c, _ in times])), float(np.median([w for _, w in times]))


def _prbs_refs(seed: int) -> np.ndarray:
    """The engine's references for `seed`, from its own generators (no plant run)."""
    from quadtank_tui.core.controllers.signals import Generator, Wave, WaveParams
    from benchmarks.experiment import AMPLITUDE, PERIOD, Y0

    gens = [Generator(WaveParams(wave=Wave.PRBS, mean=Y0[i], amplitude=AMPLITUDE, period=PERIOD,
                                 on=True, seed=(seed + i) % 2**31), H) for i in range(2)]
    return np.stack([np.array(g.take(SAMPLES)) for g in gens], axis=1)


if __name__ == "__main__":
    main()
