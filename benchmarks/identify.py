"""Time to identify from one 3600-point log, per method.

    .venv/bin/python benchmarks/identify.py [--repeat 3]

The logs are the shipped experiments at P- (params/identify-pminus-u1.yaml and
-mimo.yaml) run on the simulator (virtual clock).  Printed: the best of `--repeat`
runs of one element per method (step, oe first and second order, arx), of one
output's two elements fitted together from the MIMO log (oe), and of the 2x2
subspace model, with the load average beside them (the machine may be shared;
multi-threaded BLAS on small matrices suffers most).  Targets (issue 12): under 1 s
for a step or output-error element, under 3 s for the 2x2 subspace model.

Then the physical fit (issue 27), once each: the quadruple tank's eight constants
from 1,000 rows of the MIMO log (its 10 mV sensor noise included; target < 60 s),
and the cascade's three from 2,000 rows of its simulator at 1 s with 10 mV sensor
noise (target < 30 s), both from constants 10-20 % off; the fitted constants are
printed against the true.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from quadtank_tui.core.identify.arx import fit_arx  # noqa: E402
from quadtank_tui.core.identify.oe import fit_oe, fit_oe_miso  # noqa: E402
from quadtank_tui.core.identify.physical import (  # noqa: E402
    Experiment,
    PhysicalFit,
    experiment_from_columns,
    fit_physical,
    simulate,
)
from quadtank_tui.core.plant import P_MINUS  # noqa: E402
from quadtank_tui.core.plants import CoupledCascade, Plant, QuadTank  # noqa: E402
from quadtank_tui.core.identify.step import fit_step  # noqa: E402
from quadtank_tui.core.identify.subspace import fit_subspace  # noqa: E402
from quadtank_tui.core.identify.system import from_state_space  # noqa: E402
from quadtank_tui.engine.headless import run_headless  # noqa: E402
from quadtank_tui.files.log_reader import LogData, read_log  # noqa: E402
from quadtank_tui.files.script import read_script  # noqa: E402


def experiment(name: str, folder: Path) -> LogData:
    out = folder / f"{name}.log"
    run_headless(par="minphase", script=read_script(ROOT / f"params/identify-{name}.yaml"), duration=4200,
                 out=out, params_dir=ROOT / "params")
    return read_log(out)


def best(fn: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        simo, mimo = experiment("pminus-u1", Path(tmp)), experiment("pminus-mimo", Path(tmp))
    u1, y1, y2 = simo["u1"], simo["y1"], simo["y2"]
    U = np.column_stack([mimo["u1"], mimo["u2"]])
    Y = np.column_stack([mimo["y1"], mimo["y2"]])
    cases: list[tuple[str, Callable[[], object], float]] = [
        ("step, structure 1, n = 1 (G11)", lambda: fit_step(u1, y1, 1.0, 1, 1), 1.0),
        ("step, structure 1, n = 1..4 (G21)", lambda: fit_step(u1, y2, 1.0, 1, None), 1.0),
        ("oe, 1 pole + delay (G11)", lambda: fit_oe(u1, y1, 1.0, 1), 1.0),
        ("oe, 2 poles + delay (G21)", lambda: fit_oe(u1, y2, 1.0, 2), 1.0),
        ("oe, MISO from the MIMO log (G21, G22)", lambda: fit_oe_miso(U, Y[:, 1], 1.0, [2, 1]), 3.0),
        ("arx(2, 2, 1) (G21)", lambda: fit_arx(u1, y2, 1.0, 2, 2, 1), 1.0),
        ("n4sid, 4 states, 2x2", lambda: from_state_space(*_abc(fit_subspace(U, Y, 1.0, 4))), 3.0),
    ]
    print(f"3600 rows at 1 s; best of {args.repeat}; load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores")
    for name, fn, target in cases:
        t = best(fn, args.repeat)
        print(f"  {name:<36} {t * 1e3:8.0f} ms   (target < {target:g} s{'' if t < target else ', MISSED'})")
    physical(mimo)


def physical(mimo: LogData) -> None:
    """The physical fits, once each, with the constants against the true ones."""
    quad = QuadTank(P_MINUS.params)
    rows = 1000
    exp = experiment_from_columns("pminus-mimo", 1.0, {k: v[:rows] for k, v in mimo.columns().items()}, quad)
    start = quad.with_values(a1=0.064, a2=0.063, a3=0.078, a4=0.051, k1=3.0, k2=3.7, gamma1=0.63, gamma2=0.66)
    _physical_case(f"quadruple tank, 8 constants, {rows} rows", quad, start, [exp], 60.0)
    cascade = CoupledCascade()
    rows, rng = 2000, np.random.default_rng(1)
    u = np.repeat(6.0 + 2.0 * rng.choice([-1.0, 1.0], size=rows // 40 + 1), 40)[:rows, None]
    y = simulate(cascade, (10.0, 9.0), u, 1.0) * np.array([cascade.kc1, cascade.kc2])
    y += 0.01 * rng.standard_normal(y.shape)
    start = cascade.with_values(alpha1=0.009, alpha2=0.0115, beta1=0.27)
    _physical_case(f"cascade, 3 constants, {rows} rows, noise", cascade, start,
                   [Experiment("cascade", 1.0, u, y, (0, 1))], 30.0)


def _physical_case(name: str, true: Plant, start: Plant, exps: list[Experiment], target: float) -> None:
    t0 = time.perf_counter()
    fit: PhysicalFit = fit_physical(start, exps)
    t = time.perf_counter() - t0
    print(f"  physical: {name:<38} {t:6.1f} s   (target < {target:g} s{'' if t < target else ', MISSED'}; "
          f"{fit.evaluations} simulations, RMS {fit.rms:.3g} V)")
    for e in fit.constants:
        value = true.values()[e.name]
        print(f"    {e.name:<7} true {value:<10.6g} start {e.start:<10.6g} fitted {e.value:<12.8g} "
              f"+- {e.stderr:<9.2g} error {100 * (e.value / value - 1):+.4f} %")


def _abc(fit):  # type: ignore[no-untyped-def]
    return fit.A, fit.B, fit.C


if __name__ == "__main__":
    main()
