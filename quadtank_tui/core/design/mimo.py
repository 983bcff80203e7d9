"""The 2x2 check of a decentralized PI/PID design on the quadruple tank.

Each diagonal loop is designed on its element of G (the physical linearization,
core.analysis, or identified elements), then the whole loop is checked with the
off-diagonal elements present: closed-loop poles of the linear 2x2 system, the
relative gain lambda11 = g11 g22 / (g11 g22 - g12 g21) at s = 0 and at each loop's
crossover.

Why a second loop can need another design: with integral action in both loops,
the closed loop can be stable only if det G(0) has the sign of g11(0) g22(0)
(lambda11(0) > 0; Grosdidier, Morari & Holt 1985).  At P+ det G(0) < 0, so no
pair of PIs with the signs of the diagonal gains (both positive) stabilizes it.
Loop 2 is then designed on what it sees with loop 1 closed,

    g22_eff = g22 - g12 g21 c1 / (1 + c1 g11),

whose gain at s = 0 is det G(0)/g11(0) < 0: an Ms-constrained PI on it (whatever
the method of loop 1) gives K2 < 0, as the thesis did (Johansson & Nunes: (1.5, 110) and (-0.12, 220)); g22_eff has the right-half-
plane zero, so that loop is slow.

Units: G in V/V from pump voltage to level-sensor voltage, which is also the
ratio of the program's normalized signals (1.0 = 10 V), so Kc is the PID element's K.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import numpy.typing as npt
from scipy.signal import BadCoefficients, ss2tf, tf2ss

from quadtank_tui.core.analysis import analyze
from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.design.evaluate import evaluate
from quadtank_tui.core.design.evaluation import Evaluation
from quadtank_tui.core.design.lambda_tuning import default_lambda, first_order, lambda_pi
from quadtank_tui.core.design.optimize import pi_ms, pid_ms
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import PlantParams
from quadtank_tui.core.parameters import Parameters
from quadtank_tui.core.plants.base import Plant

Matrix = tuple[tuple[DelayTF, DelayTF], tuple[DelayTF, DelayTF]]



def physical_model(p: PlantParams, h0: Sequence[float]) -> Matrix:
    """The linearization's G(s) as DelayTFs (no dead time), V/V."""
    a = analyze(p, h0)

    def tf(i: int, j: int) -> DelayTF:
        e = a.G[i][j]
        den = np.array([1.0])
        for T in e.lags:
            den = np.polymul(den, [T, 1.0])
        return DelayTF((e.gain,), tuple(den))

    return ((tf(0, 0), tf(0, 1)), (tf(1, 0), tf(1, 1)))


def plant_matrix(plant: Plant, levels: Sequence[float]) -> Matrix:
    """The 2x2 model of any plant with two pumps and two controlled levels (core.plants),
    linearized at the steady state through its controlled operating levels, in
    normalized units (1.0 = a pump's full scale in, 10 V of sensor out): the
    identified models' and the PID elements' units."""
    if len(plant.inputs) != 2 or len(plant.controlled) != 2:
        raise DesignError(f"{plant.title} has {len(plant.inputs)} pump(s) and {len(plant.controlled)} "
                          "controlled level(s): the 2x2 design needs two of each (design its loop "
                          "with --model)")
    given = [float(x) if i in plant.controlled else None for i, x in enumerate(levels)]
    op = plant.steady_inputs(given)
    lin = plant.control_model(op.x, op.u)
    out = []
    for i in range(2):
        row = []
        for j in range(2):
            num, den = ss2tf(lin.A, lin.B[:, [j]], lin.C[[i]], np.zeros((1, 1)))
            scale = plant.inputs[j].full_scale / FULL_SCALE_V
            n, d = _cancel(np.atleast_1d(num[0]) * scale, den)
            row.append(DelayTF(tuple(n), tuple(d)))
        out.append((row[0], row[1]))
    return (out[0], out[1])


def plant_loop(plant: Plant, levels: Sequence[float]) -> DelayTF:
    """A one-pump plant's loop (the cascade: the lower level from the pump), linearized
    at the steady state its controlled level sets, in normalized units as plant_matrix."""
    if len(plant.inputs) != 1 or len(plant.controlled) != 1:
        raise DesignError(f"{plant.title} has {len(plant.inputs)} pumps: the one-loop design is for one pump")
    (c,) = plant.controlled
    op = plant.steady_inputs([float(x) if i == c else None for i, x in enumerate(levels)])
    lin = plant.control_model(op.x, op.u)
    with warnings.catch_warnings():  # the cascade's numerator has a zero leading term: stripped below
        warnings.simplefilter("ignore", BadCoefficients)
        num, den = ss2tf(lin.A, lin.B[:, [0]], lin.C[[0]], np.zeros((1, 1)))  # C: the controlled row only
    num = np.atleast_1d(num[0])
    num = np.trim_zeros(np.where(np.abs(num) < 1e-9 * np.abs(num).max(), 0.0, num), "f")
    n, d = _cancel(num * plant.inputs[0].full_scale / FULL_SCALE_V, den)
    return DelayTF(tuple(n), tuple(d))


def model_in_use(params: Parameters) -> Matrix:
    """The physical 2x2 model of the plant in use at its operating levels: the
    quadruple tank's analytic linearization, or plant_matrix of a PLANT section."""
    if params.process is None:
        return physical_model(params.quadtank_constants(), params.operating_levels())
    return plant_matrix(params.process_plant(), params.process_levels())


def _mul(a: DelayTF, b: DelayTF) -> DelayTF:
    return DelayTF(tuple(np.polymul(a.num, b.num)), tuple(np.polymul(a.den, b.den)),
                   a.delay + b.delay)


def loop2_with_loop1_closed(G: Matrix, c1: PIDTuning) -> DelayTF:
    """g22 - g12 g21 c1/(1 + c1 g11) as one rational model; an element's dead time
    (an identified model has small ones) enters as its 2nd-order Pade approximation,
    a negligible one not at all (a higher order would only add ill-conditioned roots)."""
    cn, cd = c1.feedback_tf()
    (g11, g12), (g21, g22) = (tuple(rational(g, 2) for g in row) for row in G)
    # g12 g21 c1 / (1 + c1 g11) = n12 n21 cn d11 / (d12 d21 (cd d11 + cn n11))
    inner_den = np.polyadd(np.polymul(cd, g11.den), np.polymul(cn, g11.num))
    num_c = np.polymul(np.polymul(g12.num, g21.num), np.polymul(cn, g11.den))
    den_c = np.polymul(np.polymul(g12.den, g21.den), inner_den)
    num = np.polysub(np.polymul(g22.num, den_c), np.polymul(num_c, g22.den))
    den = np.polymul(g22.den, den_c)
    num, den = _cancel(num, den)
    return DelayTF(tuple(num), tuple(den))


def _cancel(num: np.ndarray, den: np.ndarray, tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Remove common roots (pole-zero pairs closer than tol relative), keep the gain."""
    num = np.trim_zeros(np.asarray(num, dtype=float), "f")
    den = np.trim_zeros(np.asarray(den, dtype=float), "f")
    zs, ps = list(np.roots(num)), list(np.roots(den))
    kept_z = []
    for z in zs:
        j = next((k for k, p in enumerate(ps) if abs(p - z) <= tol * max(1.0, abs(z))), None)
        if j is None:
            kept_z.append(z)
        else:
            ps.pop(j)
    gain = num[0] / den[0]
    n = np.real(np.poly(kept_z)) * gain if kept_z else np.array([gain])
    d = np.real(np.poly(ps)) if ps else np.array([1.0])
    scale = d[-1] if abs(d[-1]) > 1e-300 else d[0]  # constant term 1 where possible
    return n / scale, d / scale


def lambda11(G: Matrix, w: float) -> complex:
    """Relative gain of the diagonal pairing at frequency w (rad/s); w = 0 allowed."""
    g: list[list[complex]]  # static gains are real, a number each either way
    if w == 0.0:
        g = [[G[i][j].static_gain for j in range(2)] for i in range(2)]
    else:
        g = [[complex(G[i][j].freqresp(np.array([w]))[0]) for j in range(2)] for i in range(2)]
    det = g[0][0] * g[1][1] - g[0][1] * g[1][0]
    if det == 0:
        return complex(math.inf)
    return complex(g[0][0] * g[1][1] / det)


def _ss(num: npt.ArrayLike, den: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """State space of a proper SISO transfer function (A, B, C, D as 2-D arrays)."""
    A, B, C, D = tf2ss(np.asarray(num, dtype=float), np.asarray(den, dtype=float))
    n = A.shape[0]
    return (A.reshape(n, n), B.reshape(n, 1), C.reshape(1, n), D.reshape(1, 1))


def closed_loop_poles(G: Matrix, c1: PIDTuning, c2: PIDTuning) -> np.ndarray:
    """Poles of the decentralized 2x2 loop u_i = c_i (r_i - y_i), G strictly proper
    (a dead time is replaced by its 6th-order Pade approximation, a negligible one
    left out: NEGLIGIBLE_DELAY)."""
    blocks = []  # (i, j, A, B, C) of each element y_i += G_ij u_j
    for i in range(2):
        for j in range(2):
            g = G[i][j]
            r = rational(g, 6)
            A, B, C, D = _ss(r.num, r.den)
            if abs(D[0, 0]) > 1e-12:
                raise DesignError("the 2x2 check needs strictly proper elements")
            blocks.append((i, j, A, B, C))
    ctrl = [_ss(*c.feedback_tf()) for c in (c1, c2)]
    ng = sum(b[2].shape[0] for b in blocks)
    nc = sum(c[0].shape[0] for c in ctrl)
    Ag, Bg, Cg = np.zeros((ng, ng)), np.zeros((ng, 2)), np.zeros((2, ng))
    k = 0
    for i, j, A, B, C in blocks:
        n = A.shape[0]
        Ag[k:k + n, k:k + n], Bg[k:k + n, j], Cg[i, k:k + n] = A, B[:, 0], C[0]
        k += n
    Ac, Bc, Cc, Dc = np.zeros((nc, nc)), np.zeros((nc, 2)), np.zeros((2, nc)), np.zeros((2, 2))
    k = 0
    for i, (A, B, C, D) in enumerate(ctrl):
        n = A.shape[0]
        Ac[k:k + n, k:k + n], Bc[k:k + n, i], Cc[i, k:k + n], Dc[i, i] = A, B[:, 0], C[0], D[0, 0]
        k += n
    # u = Cc xc - Dc Cg xg (r = 0); xg' = Ag xg + Bg u; xc' = Ac xc - Bc Cg xg
    top = np.hstack([Ag - Bg @ Dc @ Cg, Bg @ Cc])
    bottom = np.hstack([-Bc @ Cg, Ac])
    return np.linalg.eigvals(np.vstack([top, bottom]))


#: a dead time below this share of an element's fastest time constant is left out of the
#: pole check: its Pade denominator (coefficients down to delay^6) would make the state
#: matrix so ill-conditioned that eigvals finds spurious right-half-plane poles (an
#: identified 1e-10 s delay gave a "pole" at +3.7 1/s); its phase lag is below 1e-3 rad
#: wherever the element's gain still matters.
NEGLIGIBLE_DELAY = 1e-3


def _fastest_time_constant(den: np.ndarray) -> float:
    """1/|fastest pole| of a denominator (s); inf for a constant one."""
    poles = np.roots(np.trim_zeros(np.asarray(den, dtype=float), "f"))
    fastest = float(np.max(np.abs(poles))) if poles.size else 0.0
    return math.inf if fastest == 0.0 else 1.0 / fastest


def rational(g: DelayTF, order: int) -> DelayTF:
    """g without dead time: the delay as a Pade approximation of `order`, or left out
    when it is below NEGLIGIBLE_DELAY of the element's fastest time constant."""
    if g.delay <= NEGLIGIBLE_DELAY * _fastest_time_constant(np.asarray(g.den)):
        return DelayTF(g.num, g.den)
    pn, pd = _pade(g.delay, order)
    return DelayTF(tuple(np.polymul(g.num, pn)), tuple(np.polymul(g.den, pd)))


def _pade(delay: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Pade approximation of e^(-delay s): (num, den) descending in s."""
    k = np.arange(order + 1)
    fact = [math.factorial(int(x)) for x in range(2 * order + 1)]
    c = np.array([fact[2 * order - i] * fact[order] / (fact[2 * order] * fact[i] * fact[order - i])
                  for i in k]) * delay ** k
    num = (c * (-1.0) ** k)[::-1]
    return num, c[::-1]


def sampled_poles(G: Matrix, c1: PIDTuning, c2: PIDTuning, h: float) -> np.ndarray:
    """z-plane poles of the 2x2 loop sampled at h: every element behind the ZOH with
    its dead time exact (whole samples and the fraction), both PIDs as core.controllers.pid runs them."""
    from quadtank_tui.core.design.sampled import closed_loop_matrix, sample

    models = [[sample(G[i][j], h) for j in range(2)] for i in range(2)]
    return np.linalg.eigvals(closed_loop_matrix(models, [c1, c2], h))


def slowest_pole(G: Matrix, c1: PIDTuning, c2: PIDTuning, h: float = 0.0) -> float:
    """The real part of the slowest closed-loop pole, 1/s (>= 0: unstable); for h > 0
    ln max|z| / h of the sampled loop's poles."""
    if h > 0.0:
        from quadtank_tui.core.design.sampled import slowest_rate

        return slowest_rate(sampled_poles(G, c1, c2, h), h)
    return float(np.max(closed_loop_poles(G, c1, c2).real))


@dataclass(frozen=True)
class LoopDesign:
    loop: int
    model: DelayTF
    how: str
    controller: PIDTuning
    evaluation: Evaluation


@dataclass(frozen=True)
class MimoCheck:
    loops: tuple[LoopDesign, LoopDesign]
    det_G0: float
    lambda11_0: float
    lambda11_wc: tuple[complex, complex]
    stable: bool
    slowest_pole: float
    notes: tuple[str, ...] = field(default=())
    #: 0: the continuous-time loop; else the sampling time the loop was designed and checked at, s
    sampling_time: float = 0.0

    def pid_pair(self) -> tuple[PIDTuning, PIDTuning]:
        return self.loops[0].controller, self.loops[1].controller


def design_loop(g: DelayTF, method: str, *, lam: float | None = None, ms: float = 1.4,
                h: float = 0.0) -> PIDTuning:
    """One loop: lambda (default: lambda_tuning.default_lambda), pi-ms or pid-ms;
    h > 0: for the loop sampled at h s."""
    if method == "lambda":
        fo = first_order(g)
        return lambda_pi(fo, default_lambda(fo) if lam is None else lam, h)
    if method in ("pi-ms", "pid-ms"):
        return pi_ms(g, ms, h=h) if method == "pi-ms" else pid_ms(g, ms, h=h)
    raise DesignError(f"unknown method {method!r}: lambda, pi-ms or pid-ms")


def design_2x2(G: Matrix, method: str = "lambda", *, lam: tuple[float | None, float | None] = (None, None),
               ms: float = 1.4, h: float = 0.0) -> MimoCheck:
    """Design both diagonal loops and check the 2x2 closed loop (see the module);
    h > 0: designs, figures and the pole check of the loop sampled at h s."""
    g11, g22 = G[0][0], G[1][1]
    notes: list[str] = []
    c1 = design_loop(g11, method, lam=lam[0], ms=ms, h=h).rounded()
    c2 = design_loop(g22, method, lam=lam[1], ms=ms, h=h).rounded()
    det0 = g11.static_gain * g22.static_gain - G[0][1].static_gain * G[1][0].static_gain
    l0 = float(lambda11(G, 0.0).real)
    how2 = "g22"
    model2 = g22
    if l0 < 0.0:
        notes.append(
            f"det G(0) = {det0:.3g} has the opposite sign of g11(0) g22(0) (lambda11(0) = {l0:.3g} < 0): "
            "no decentralized PI with the signs of the diagonal gains (both positive) stabilizes "
            "this setting")
        model2 = loop2_with_loop1_closed(G, c1)
        how2 = "g22 with loop 1 closed"
        # its right-half-plane zero bounds the gain: an Ms-constrained PI fits it (a
        # first-order fit for lambda tuning would hide the inverse response)
        c2 = pi_ms(model2, ms, h=h).rounded()
        notes.append(f"loop 2 designed on {how2} (PI, Ms {ms:g}): gain {model2.static_gain:.3g} "
                     f"at s = 0, so K2 = {c2.Kc:.3g} < 0")
    slowest = slowest_pole(G, c1, c2, h)
    stable = slowest < 0.0
    if not stable:
        notes.append(f"the 2x2 closed loop is unstable (a pole at {slowest:.3g} 1/s)")
    ev1 = evaluate(c1, g11, h=h)
    ev2 = evaluate(c2, model2, h=h)
    wc = (lambda11(G, ev1.crossover), lambda11(G, ev2.crossover))
    loops = (LoopDesign(1, g11, "g11", c1, ev1), LoopDesign(2, model2, how2, c2, ev2))
    return MimoCheck(loops, det0, l0, wc, stable, slowest, tuple(notes), h)


def format_check(check: MimoCheck) -> str:
    """The MIMO check as text (CLI and screen)."""
    where = (f"sampled at h = {check.sampling_time:g} s (ZOH, core.controllers.pid's PID)" if check.sampling_time > 0
             else "continuous time")
    lines = [f"det G(0) = {check.det_G0:.4g}   lambda11(0) = {check.lambda11_0:.3f}   {where}"]
    for d, lw in zip(check.loops, check.lambda11_wc):
        e = d.evaluation
        lines.append(
            f"loop {d.loop} on {d.how}: {d.controller.describe()}   Ms {e.Ms:.2f}  "
            f"phi_m {e.phase_margin_deg:.0f} deg  wc {e.crossover:.3g} rad/s  "
            f"|lambda11(i wc)| {abs(lw):.2f}")
    lines.append(("closed loop stable" if check.stable else "closed loop UNSTABLE")
                 + f" (slowest pole {check.slowest_pole:.3g} 1/s)")
    lines.extend(check.notes)
    return "\n".join(lines)
