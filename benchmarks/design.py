"""Design speed: one PI_opt, one PID (Ms-constrained) and a full comparison table
(3 lambdas + PI and PID at Ms 1.6/1.4/1.2, each evaluated: 9 controllers).

    .venv/bin/python benchmarks/design.py

Targets (issue 13, so the Design screen stays interactive): a design under 0.3 s,
the table under 2 s.  Andersson's process 1 (1.6592 e^-2.4s/(1.07s+1)^3) and
process 2's simulation model (-0.00652 e^-2s/(s(49.33s+1)), the slowest to
simulate: 5000-s responses).  Best of 3 runs; figures are printed, not asserted.

Issue 23: the same table designed and evaluated for the loop sampled at 0.1 s and
1 s (with the limit check), and the preview of the P- lambda pair on the
nonlinear plant (a step on each loop; target under 1 s).
"""

from __future__ import annotations

import time
from typing import Callable

from quadtank_tui.core.design.expr import parse_model
from quadtank_tui.core.design.optimize import pi_ms, pid_ms
from quadtank_tui.core.design.mimo import design_2x2, model_in_use
from quadtank_tui.core.design.preview import preview
from quadtank_tui.core.design.table import candidates, format_table
from quadtank_tui.core.parameters import PRESET

MODELS = {
    "process 1": "1.6592*exp(-2.4*s)/(1.07*s+1)^3",
    "process 2": "-0.00652*exp(-2*s)/(s*(49.33*s+1))",
}


def best_of(f: Callable[[], object], n: int = 3) -> float:
    times = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    pi_ms(parse_model(MODELS["process 1"]), 1.4)  # warm the imports
    for name, text in MODELS.items():
        g = parse_model(text)
        t_pi = best_of(lambda: pi_ms(g, 1.4))
        t_pid = best_of(lambda: pid_ms(g, 1.4))
        t_table = best_of(lambda: candidates(g), n=2)
        print(f"{name}: PI_opt {t_pi * 1000:.0f} ms, PID {t_pid * 1000:.0f} ms (target 300), "
              f"9-controller table {t_table:.2f} s (target 2)")
        for h in (0.1, 1.0):
            t_sampled = best_of(lambda: candidates(g, h=h), n=2)
            print(f"  sampled at {h:g} s: 9-controller table with the limit check {t_sampled:.2f} s (target 2)")
    G = model_in_use(PRESET)
    plant, levels = PRESET.process_plant(), PRESET.process_levels()
    op = plant.steady_inputs([levels[0], levels[1], None, None])
    for h in (1.0, 0.1):
        chk = design_2x2(G, h=h)
        pv = preview(plant, op.x, op.u, chk.pid_pair(), h, model=G)
        t_pv = best_of(lambda: preview(plant, op.x, op.u, chk.pid_pair(), h, model=G), n=2)
        ran = ", ".join(f"{s.window:.0f} s" for s in pv.steps)
        print(f"P- lambda pair, preview on the nonlinear plant at {h:g} s (until settled: {ran}): "
              f"{t_pv:.2f} s (target 1)")
    print()
    print("process 1 table:")
    print(format_table(candidates(parse_model(MODELS["process 1"]))))


if __name__ == "__main__":
    main()
