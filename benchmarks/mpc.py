"""MPC (issue 26): solve time per sample, and the closed loop against the files' PI.

    .venv/bin/python benchmarks/mpc.py [--quick]

1. Solve time per sample (KF update, targets, QP update, OSQP solve with polishing)
   at the files' sampling time (0.1 s), horizons 30 and 60 on the loop's grid and 60
   on a 2-s prediction grid (the same QP size), at P- and P+, over 300 s
   of the nonlinear plant with a 5 cm step announced at 40 s on loop 1, one on loop 2
   at 120 s and a leak in tank 1 at 200 s: p50 / p99 / max of the wall clock and of
   the thread's CPU time (the machine is shared: the load average is printed).
   Target: p99 under 5 ms (a tenth of the shortest sampling time, 50 ms).
2. The closed loop (core.controllers.mpc.simulate.standard_scenario: an announced step on each
   loop, then a leak of 0.15 a1 in tank 1) under MPC (N = 60 steps of 2 s with
   preview: 120 s ahead, the estimator and the solve every sample) and under the
   file's PI matrix, at P- and P+, at the lab's 0.1 s: IAE per loop over each step's
   phase (the announced steps) and over the leak, overshoot, seconds at a pump limit,
   samples with a level beyond its limit, failed solves, solve time p50 / p99.  At
   P+ also N = 60 on the loop's grid (6 s ahead), which the 2-s grid replaces.
   Targets: MPC's step IAE at most 0.8 of PI's on both loops, pumps inside 0..10 V.
   --quick samples at 1 s.
Figures are printed, not asserted.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

from quadtank_tui.core.controllers.matrix import ELEMENTS, ControllerMatrix
from quadtank_tui.core.controllers.mpc.predictive import MPC, design_mpc
from quadtank_tui.core.controllers.mpc.model import plant_in_use
from quadtank_tui.core.controllers.mpc.settings import MPCSettings
from quadtank_tui.core.controllers.mpc.simulate import Run, Scenario, figures, run_mpc, run_pi, standard_scenario
from quadtank_tui.files.par import read_par

PARAMS = Path(__file__).resolve().parents[1] / "params"
SETTINGS = (("P-", "minphase", 300.0), ("P+", "nonminphase", 600.0))
#: The MPC compared: 60 prediction steps of 2 s (rounded to whole samples).
HORIZON, STEP = 60, 2.0


def _params(name: str, tsamp: float | None = None):
    p = read_par(PARAMS / f"{name}.par").params
    return p if tsamp is None else p.with_values({"SAMPLING TIME.TSamp": tsamp * 1000.0})


def solve_times() -> None:
    print(f"1. solve time per sample, T = 0.1 s, 300 s of plant (load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores)")
    print(f"{'':4} {'N':>8} {'wall p50':>9} {'p99':>7} {'max':>7}   {'CPU p50':>8} {'p99':>7} {'max':>7}  "
          f"{'fail':>4}  ms")
    for label, name, _ in SETTINGS:
        p = _params(name)
        plant, levels = plant_in_use(p)
        for N, step in ((30, 0.0), (60, 0.0), (HORIZON, STEP)):
            d = design_mpc(plant, levels, MPCSettings(horizon=N, step=step), p.tsamp)
            x_e = tuple(d.model.x_e)
            scn = Scenario((x_e[0], x_e[1]), ((40.0, 0, x_e[0] + 5.0), (120.0, 1, x_e[1] + 3.0)),
                           (200.0, 1, 0.15 * plant.values()["a1"]), 300.0)
            mpc = MPC(d)
            run_mpc(plant, mpc, x_e, scn)
            w = np.array(mpc.stats.times[1:]) * 1e3  # the first solve starts OSQP cold
            c = np.array(mpc.stats.cpu_times[1:]) * 1e3
            grid = f"{N}x{d.prediction.T:g}s"
            print(f"{label:4} {grid:>8} {np.percentile(w, 50):9.2f} {np.percentile(w, 99):7.2f} {w.max():7.2f}   "
                  f"{np.percentile(c, 50):8.2f} {np.percentile(c, 99):7.2f} {c.max():7.2f}  {mpc.stats.faults:4d}")


def _phase_iae(run: Run, plant, scn: Scenario) -> list[list[float]]:
    """IAE per loop over each phase: the steps' (one per loop) and the leak's."""
    T = float(run.t[1] - run.t[0])
    edges = [st[0] for st in scn.steps] + ([scn.leak[0]] if scn.leak else []) + [scn.duration]
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        w = (run.t >= a - T / 2) & (run.t < b - T / 2)
        out.append([float(np.sum(np.abs(run.r[w, loop] - run.x[w, i])) * T)
                    for loop, i in enumerate(plant.controlled)])
    return out


def closed_loop(tsamp: float) -> None:
    print(f"\n2. closed loop on the nonlinear plant, T = {tsamp:g} s, MPC N = {HORIZON} steps of {STEP:g} s "
          f"with preview vs the file's PI")
    for label, name, phase in SETTINGS:
        p = _params(name, tsamp)
        plant, levels = plant_in_use(p)
        d = design_mpc(plant, levels, MPCSettings(horizon=HORIZON, step=STEP), p.tsamp)
        mdl = d.model
        x_e, u_e = tuple(mdl.x_e), tuple(mdl.u_e)
        scn = standard_scenario(plant, x_e, phase=phase, lead=HORIZON * d.prediction.T + 10.0)
        t0 = time.perf_counter()
        runs = {"MPC": run_mpc(plant, MPC(d), x_e, scn)}
        if label == "P+" and d.step_samples > 1:  # what the coarse grid replaces: N steps of one sample
            short = design_mpc(plant, levels, MPCSettings(horizon=HORIZON), p.tsamp)
            runs[f"{HORIZON * tsamp:g}s"] = run_mpc(plant, MPC(short), x_e, scn)
        matrix = ControllerMatrix(p.tsamp, p.control.family, p.control.structure,
                                  pid={e: c.pid for e, c in zip(ELEMENTS, p.controllers)})
        runs["PI"] = run_pi(plant, matrix, x_e, u_e, scn)
        steps = ", ".join(f"r{loop + 1} {level - x_e[loop]:+.1f} cm at {t:g} s" for t, loop, level in scn.steps)
        assert scn.leak is not None
        print(f"\n{label} ({name}.par): {steps}; leak tank 1 at {scn.leak[0]:g} s; {scn.duration:g} s "
              f"({time.perf_counter() - t0:.0f} s to simulate)")
        print(f"{'':4} {'IAE step1':>18} {'IAE step2':>18} {'IAE steps':>18} {'IAE leak':>18} {'OS %':>11} "
              f"{'limit s':>7} {'viol':>5} {'fail':>4} {'u range V':>11} {'max level':>9} {'p50 ms':>6} {'p99':>5}")
        iae = {}
        for ctl, run in runs.items():
            f = figures(plant, run, scn, mdl.x_lo, mdl.x_hi)
            ph = _phase_iae(run, plant, scn)
            steps_iae = [ph[0][k] + ph[1][k] for k in range(2)]
            iae[ctl] = steps_iae
            cells = [f"{a:8.1f} {b:8.1f}" for a, b in (ph[0], ph[1], steps_iae, ph[2])]
            print(f"{ctl:>4} {cells[0]:>18} {cells[1]:>18} {cells[2]:>18} {cells[3]:>18} "
                  f"{f.overshoot[0]:5.1f} {f.overshoot[1]:5.1f} {f.at_limit:7.1f} {f.violations:5d} {f.faults:4d} "
                  f"{run.u.min():5.2f}-{run.u.max():5.2f} {run.x.max():9.2f} {f.p50_ms:6.2f} {f.p99_ms:5.2f}")
        for ctl in iae:
            if ctl != "PI":
                ratio = [m / q for m, q in zip(iae[ctl], iae["PI"])]
                print(f"{ctl}/PI step IAE: loop 1 {ratio[0]:.2f}, loop 2 {ratio[1]:.2f} (target <= 0.8)")


def main() -> None:
    quick = "--quick" in sys.argv[1:]
    solve_times()
    closed_loop(1.0 if quick else 0.1)


if __name__ == "__main__":
    main()
