"""Design speed: one PI_opt, one PID (Ms-constrained) and a full comparison table
(3 lambdas + PI and PID at Ms 1.6/1.4/1.2, each evaluated: 9 controllers).

    .venv/bin/python benchmarks/design.py

Targets (issue 13, so the Design screen stays interactive): a design under 0.3 s,
the table under 2 s.  Andersson's process 1 (1.6592 e^-2.4s/(1.07s+1)^3) and
process 2's simulation model (-0.00652 e^-2s/(s(49.33s+1)), the slowest to
simulate: 5000-s responses).  Best of 3 runs; figures are printed, not asserted.
"""

from __future__ import annotations

import time
from typing import Callable

from quadtank_tui.core.design.expr import parse_model
from quadtank_tui.core.design.optimize import pi_ms, pid_ms
from quadtank_tui.core.design.table import candidates, format_table

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
    print()
    print("process 1 table:")
    print(format_table(candidates(parse_model(MODELS["process 1"]))))


if __name__ == "__main__":
    main()
