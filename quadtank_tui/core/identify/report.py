"""An identification as text (the CLI's report, the screen's table) and as a
JSON-ready dict, with the physical model beside it."""

from __future__ import annotations

from typing import Any

import numpy as np

from quadtank_tui.core.identify.compare import Comparison, physical_time_constants
from quadtank_tui.core.identify.experiment import Element, Identification
from quadtank_tui.core.identify.system import element_zeros, time_constants
from quadtank_tui.core.plants.common import FULL_SCALE_V


def phase(ident: Identification) -> str:
    """The 2x2 model's phase; for a model that is not square and complete, whether
    any element has a zero in the right half-plane."""
    if ident.system.zeros or (ident.system.complete and len(ident.inputs) == len(ident.outputs) > 1):
        return ident.system.phase
    rhp = any(z.real >= 0 for e in ident.elements.values() for z in element_zeros(e.tf))
    return "nonminimum" if rhp else "minimum"


def zero_text(zeros: tuple[complex, ...] | list[complex]) -> str:
    if not len(zeros):
        return "none"
    return ", ".join(f"{z.real:+.4f}" if z.imag == 0 else f"{z.real:+.4f}{z.imag:+.4f}j" for z in zeros)


def element_text(e: Element) -> str:
    """The model of one element, in the form its method fits."""
    p = e.params
    if e.kind == "step":
        keys = [k for k in ("K", "T", "Tz", "n", "L") if k in p]
        return f"[{p['structure']}] {p['form']}: " + "  ".join(
            f"{k}={p[k]:d}" if k == "n" else f"{k}={p[k]:.4g}" for k in keys)
    if e.kind == "oe":
        zeros = "".join(f"(1{tz:+.3g}s)" for tz in p["Tz"])
        poles = "".join(f"(1+{T:.3g}s)" for T in p["T"])
        delay = f" e^-{p['L']:.3g}s" if p["L"] > 1e-6 else ""
        return f"{p['K']:.4g}{zeros}/{poles}{delay}"
    return f"K={e.tf.static_gain:.4g}, poles: " + pole_text(np.roots(np.asarray(e.tf.den, dtype=float)))


def pole_text(poles: np.ndarray) -> str:
    """Every pole as it is: a real stable one as its time constant, a complex pair
    named as one (with its natural frequency and damping), never folded into a list
    of time constants."""
    parts = []
    for p in sorted(poles, key=lambda z: (abs(z.imag) > 1e-12, -z.real)):
        if abs(p.imag) <= 1e-12 * max(abs(p), 1.0):
            parts.append(f"T={-1 / p.real:.3g} s" if p.real < 0 else f"{p.real:+.4g} /s (unstable)"
                         if p.real > 0 else "integrator")
        elif p.imag > 0:
            wn = abs(p)
            parts.append(f"complex pair {p.real:+.4g}±{p.imag:.4g}j /s (wn {wn:.3g} rad/s, zeta {-p.real / wn:.2f})")
    return ", ".join(parts) if parts else "none (a static gain)"


def format_report(ident: Identification, cmp: Comparison | None, physical_name: str) -> str:
    ins, outs = ident.inputs, ident.outputs
    first = next(iter(ident.elements.values()))
    where = f"the last {100 * (1 - first.split / len(first.y)):.0f} %" if first.split else "all rows"
    lines = [f"Method {ident.method} on {', '.join(ident.records)}; TSamp {ident.h:g} s; validated on {where}"]
    op = ident.operating_point
    lines.append("Operating point (first row): " + "  ".join(
        f"{k} {v:.4f} ({v * FULL_SCALE_V:.2f} V)" for k, v in op.items()))
    lines.append("")
    lines.append("Elements (fit on the validation part; loss sum (y - ym)^2 / N on the identification part;")
    lines.append("          residual autocorrelation and input cross-correlation lags inside the 99 % band):")
    for (o, i), e in ident.elements.items():
        lines.append(f"  G{o[1:]}{i[1:]}  {element_text(e)}")
        lines.append(f"       fit {e.fit_percent:.1f} %  loss {e.loss:.3g}  white {100 * e.whiteness:.0f} %"
                     f"  independent {100 * e.independence:.0f} %  ({e.record})")
    lines.append("")
    gains = ident.system.static_gains
    if cmp is None:
        lines.append("Static gains (V/V): " + "  ".join(
            f"G{o[1:]}{i[1:]} {gains[a, b]:.4g}" for a, o in enumerate(outs) for b, i in enumerate(ins)))
    else:
        a = cmp.physical
        lines.append(f"Physical model: {physical_name}, linearized at the log's levels "
                     + " ".join(f"{h:.2f}" for h in cmp.levels) + " cm")
        lines.append("         gain identified  physical   error   time constants (s) identified | physical")
        for r, o in enumerate(outs):
            for c, i in enumerate(ins):
                e = ident.elements[(o, i)]
                tid = ", ".join(f"{t:.1f}" for t in time_constants(e.tf))
                tph = ", ".join(f"{t:.1f}" for t in physical_time_constants(a, o, i))
                phys = a.static_gains[int(o[1]) - 1, int(i[1]) - 1]
                lines.append(f"  G{o[1:]}{i[1:]}     {gains[r, c]:10.4f} {phys:9.4f} {100 * cmp.gain_error[r, c]:+6.1f} %"
                             f"   {tid} | {tph}")
    lines.append(f"Transmission zeros: {zero_text(ident.system.zeros)}" + (
        f"   (physical: {zero_text(cmp.physical.zeros)})" if cmp is not None else ""))
    lines.append(f"Phase: {phase(ident)}" + (f"   (physical: {cmp.physical.phase})" if cmp is not None else ""))
    lines.append("Fit on the validation part: " + "  ".join(f"{o} {f:.1f} %" for o, f in ident.fit_percent.items()))
    return "\n".join(lines)


def to_dict(ident: Identification, cmp: Comparison | None, physical_name: str) -> dict[str, Any]:
    gains = ident.system.static_gains
    out: dict[str, Any] = {
        "method": ident.method,
        "logs": list(ident.records),
        "sampling_time": ident.h,
        "inputs": list(ident.inputs),
        "outputs": list(ident.outputs),
        "operating_point": ident.operating_point,
        "static_gains": np.where(np.isfinite(gains), gains, np.nan).tolist(),
        "zeros": [[z.real, z.imag] for z in ident.system.zeros],
        "phase": phase(ident),
        "fit_percent": ident.fit_percent,
        "elements": [e.to_dict() for e in ident.elements.values()],
        # dx/dt = A x + B u, y = C x, in deviations from the operating point (dead
        # times left out); block-diagonal when the elements were fitted one by one.
        "state_space": {"A": ident.system.A.tolist(), "B": ident.system.B.tolist(),
                        "C": ident.system.C.tolist()},
    }
    if cmp is not None:
        out["physical"] = {"model": physical_name, **cmp.physical.to_dict()}
        out["gain_error"] = cmp.gain_error.tolist()
    return out
