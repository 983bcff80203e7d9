"""Andersson's figures for the sampled loop, and the actuator-limit check.

Every figure here is the discrete loop's (core.design.sampled): Ms and the margins
of L(e^(iwh)), 0 < w < pi/h; stability from the closed-loop eigenvalues; IAE, Emax
and u overshoot of Andersson's load step (size 10/K, unlimited, as his tables);
then the two steps the rig would see, with the pumps limited to 0..1 (0..10 V)
around the operating input u0: a reference step of STEP (10 % of the range) and a
load step of STEP at the process input.  A candidate is marked when either step
sits at a pump limit for more than a fifth of its settling time (or never
settles), or when its input reverses direction on most samples (chatter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError
from quadtank_tui.core.design.evaluation import Evaluation, load_size
from quadtank_tui.core.design.simulate import Response
from quadtank_tui.core.design.sampled import (
    SampledModel, closed_loop_matrix, closed_loop_poles, controller_freqresp, controller_ss, derivative_gain, sample,
    sampled_grid,
    slowest_rate,
)
from quadtank_tui.core.metrics import loop_metrics
from quadtank_tui.core.controllers.pid import PID as RunningPID
from quadtank_tui.core.controllers.pid import PIDParams

#: reference and load step of the limit check, normalized (10 % of the pump/sensor range)
STEP = 0.1
#: a step that sits at a pump limit longer than this share of its settling time is marked
SATURATION_SHARE = 0.2
#: an input reversing direction on more than this share of its moving samples chatters
CHATTER_SHARE = 0.5
#: anti-windup tracking time of the simulated PID when none is given (the .par default)
TR_DEFAULT = 1.0
MAX_SAMPLES = 40_000


def running_pid(c: PIDTuning, h: float, tr: float = TR_DEFAULT) -> RunningPID:
    """The PID element core.controllers.pid runs, with this design's settings."""
    if abs(c.Kc) > 1e3:
        raise DesignError(f"Kc = {c.Kc:.4g}: beyond the PID element's range (|K| <= 1000)")
    integral = math.isfinite(c.Ti) and c.Ti < 1e6
    params = PIDParams(K=c.Kc, Ti=c.Ti if integral else 1e6, Td=c.Td, Tr=tr, N=c.N, b=c.b,
                       integral=integral, derivative=c.Td > 0.0)
    return RunningPID(params, h)


def simulate(m: SampledModel, c: PIDTuning, *, r: float = 0.0, d: float = 0.0, samples: int,
             limits: tuple[float, float] = (-math.inf, math.inf), tr: float = TR_DEFAULT) -> Response:
    """From rest (deviations), a reference step r and a load step d at the process
    input at sample 0; the controller output clipped to `limits` (deviation).

    The controller is core.controllers.pid's algorithm sample by sample (P on b r - y, the
    backward-difference derivative on y, the forward-difference integral with the
    back-calculation anti-windup h/Tr (u - v); tests/core/design check it against
    core.controllers.pid.PID to rounding).  While the output stays inside the limits the loop
    is linear: from each unsaturated sample the rest is propagated in blocks
    (`propagate`), and kept up to the first sample it would leave the limits."""
    if m.Dd != 0.0:
        raise DesignError("the sampled model passes its input straight through (no delay, biproper)")
    running_pid(c, m.h, tr)  # the element's own range checks
    A, B, C = m.A, m.B, m.C
    lo, hi = limits
    h = m.h
    K, b = c.Kc, c.b
    ki = K * h / c.Ti if math.isfinite(c.Ti) else 0.0
    aw = h / tr
    ad, gd = derivative_gain(c, h)
    bd = K * gd
    has_d = c.Td > 0.0
    n = A.shape[0]
    Acl = closed_loop_matrix([[m]], [c], h)
    Ac, Bc, Cc, Dc = controller_ss(c, h)
    nc = Ac.shape[0]
    u_r = K * b * r
    const = np.zeros(n + nc)
    const[:n] = B * (u_r + d)
    const[n] = ki * r
    out = np.vstack([np.concatenate([C, np.zeros(nc)]), np.concatenate([Dc * C, Cc])])
    x = np.zeros(n)
    I = D = yprev = 0.0
    y = np.empty(samples)
    u = np.empty(samples)
    k = 0
    free = True  # the last sample was inside the limits: try the linear shot
    while k < samples:
        if free:
            z0 = np.concatenate([x, [I, D, yprev] if has_d else [I]])
            yu = propagate_from(Acl, const, out, z0, samples - k)
            v = yu[:, 1] + u_r
            bad = np.nonzero((v < lo) | (v > hi))[0]
            stop = int(bad[0]) if bad.size else samples - k
            y[k:k + stop], u[k:k + stop] = yu[:stop, 0], v[:stop]
            if stop == samples - k:
                break
            if stop > 0:  # the states at the first limited sample, from the same recursion
                zs = propagate_from(Acl, const, np.eye(n + nc), z0, stop + 1)[stop]
                x = zs[:n]
                I = float(zs[n])
                if has_d:
                    D, yprev = float(zs[n + 1]), float(zs[n + 2])
                k += stop
        yk = float(C @ x)
        Dk = ad * D - bd * (yk - yprev) if has_d else 0.0
        vk = K * (b * r - yk) + I + Dk
        uk = lo if vk < lo else hi if vk > hi else vk
        I += ki * (r - yk) + aw * (uk - vk)
        D, yprev = Dk, yk
        y[k], u[k] = yk, uk
        x = A @ x + B * (uk + d)
        free = uk == vk
        k += 1
    return Response(np.arange(samples) * h, y, u, r, d)


def linear_response(m: SampledModel, c: PIDTuning, *, r: float = 0.0, d: float = 0.0, samples: int) -> Response:
    """`simulate` without limits: the closed-loop state recursion in blocks."""
    return simulate(m, c, r=r, d=d, samples=samples)


def propagate(A: np.ndarray, const: np.ndarray, out: np.ndarray, samples: int, block: int = 200) -> np.ndarray:
    """out @ z_k for k < samples from z_0 = 0 (see propagate_from)."""
    return propagate_from(A, const, out, np.zeros(A.shape[0]), samples, block)


def propagate_from(A: np.ndarray, const: np.ndarray, out: np.ndarray, z0: np.ndarray, samples: int,
                   block: int = 200) -> np.ndarray:
    """out @ z_k for k < samples, z_(k+1) = A z_k + const: a block of samples per
    matrix product (z_(k+j) = A^j z_k + sum_(i<j) A^i const, j = 0..block-1).

    An unstable A (a limited loop's linear shot past the sample where the limits
    take over, a candidate the check flags) grows to inf and nan in the later rows;
    the callers keep only the rows before the limits take over (simulate), or drop a
    shot that crosses them (the preview: nan crosses), so the overflow is no fault
    to report: numpy's RuntimeWarnings for it are silenced here (every CI run printed
    four, for one design test)."""
    with np.errstate(over="ignore", invalid="ignore"):
        n = A.shape[0]
        # the powers take block n^2 numbers: a long dead time (many buffer states) gets shorter blocks
        block = max(1, min(block, samples, 4_000_000 // (n * n)))
        powers = np.empty((block, n, n))
        sums = np.empty((block, n))
        P, S = np.eye(n), np.zeros(n)
        for j in range(block):  # A^j and sum_(i<j) A^i const, j = 0..block-1
            powers[j], sums[j] = P, S
            S = A @ S + const
            P = A @ P
        OP = np.einsum("pn,jnm->jpm", out, powers)  # out A^j
        OS = sums @ out.T
        res = np.empty((samples, out.shape[0]))
        z = np.asarray(z0, dtype=float)
        for k0 in range(0, samples, block):
            j = min(block, samples - k0)
            res[k0:k0 + j] = OP[:j] @ z + OS[:j]
            z = P @ z + S  # A^block z + sum_(i<block) A^i const
        return res


def reversals(u: np.ndarray, step: float) -> float:
    """Share of the input's moves that reverse the direction of the move before
    (moves below 1e-3 of the step or of the largest move are not moves): about 1
    for a pump flipping between its limits, whatever the dwell at each."""
    du = np.diff(np.asarray(u, dtype=float))
    if du.size == 0:
        return 0.0
    moves = du[np.abs(du) > 1e-3 * max(abs(step), float(np.max(np.abs(du))))]
    if moves.size < 6:
        return 0.0
    return float(np.count_nonzero(np.sign(moves[1:]) != np.sign(moves[:-1]))) / (moves.size - 1)


@dataclass(frozen=True)
class StepFigures:
    """One limited step of the sampled loop."""

    overshoot_pct: float
    settling: float | None  # 2 % band, s
    iae: float
    at_limit: float  # s at a pump limit
    reversals: float  # share of moving samples

    @property
    def saturated(self) -> bool:
        if self.settling is None:
            return self.at_limit > 0.0
        return self.at_limit > SATURATION_SHARE * max(self.settling, 1e-9)


def step_figures(resp: Response, limits: tuple[float, float], h: float) -> StepFigures:
    """Figures of a reference step (r != 0) or a load step (error to zero)."""
    at = (resp.u <= limits[0] + 1e-9) | (resp.u >= limits[1] - 1e-9)
    size = resp.r if resp.r != 0.0 else resp.d
    if resp.r != 0.0:
        t = np.concatenate([[-h], resp.t])
        lm = loop_metrics(t, np.concatenate([[0.0], resp.y]), np.concatenate([[0.0], np.full(resp.y.size, resp.r)]))
        over, settle, iae = float(lm.overshoot or 0.0), lm.settling_time, lm.iae
    else:
        e = np.abs(resp.y)
        peak = float(e.max()) if e.size else 0.0
        outside = np.nonzero(e > 0.02 * max(peak, 1e-300))[0]
        settle = None if outside.size and outside[-1] + 1 >= e.size else (
            float(resp.t[outside[-1] + 1]) if outside.size else 0.0)
        over, iae = 0.0, float(np.sum(e) * h)
    return StepFigures(over, settle, iae, float(at.sum()) * h, reversals(resp.u, size))


@dataclass(frozen=True)
class LimitCheck:
    """The reference and load steps with the pumps limited, and the verdict."""

    u0: float
    reference: StepFigures
    load: StepFigures

    @property
    def saturates(self) -> bool:
        return self.reference.saturated or self.load.saturated

    @property
    def chatters(self) -> bool:
        return max(self.reference.reversals, self.load.reversals) > CHATTER_SHARE

    @property
    def problem(self) -> str | None:
        """Why this candidate must not be suggested (None: it holds)."""
        if self.chatters:
            return "chatters: the pump reverses on most samples"
        for name, s in (("reference", self.reference), ("load", self.load)):
            if s.settling is None:
                return f"the {name} step does not settle"
        if self.saturates:
            return "at a pump limit for more than a fifth of the settling time"
        return None


@dataclass(frozen=True)
class SampledEvaluation:
    evaluation: Evaluation
    limits: LimitCheck | None


def sampled_loop_response(c: PIDTuning, g: DelayTF, h: float, m: SampledModel | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """(w rad/s, L(e^(iwh))) of the loop sampled at h: the curve the sampled Ms and
    margins are read from (and a figure draws)."""
    w = sampled_grid(g, h)
    return w, controller_freqresp(c, h, w) * (m or sample(g, h)).freqresp(w)


def reference_step(c: PIDTuning, g: DelayTF, h: float, samples: int | None = None) -> Response:
    """The sampled loop's unit reference step, as long as its evaluation simulates it."""
    m = sample(g, h)
    if samples is None:
        ms, pm, am, lm, wc = _margins(m, c, g, h, True)
        samples = _horizon(c, wc, h)
    return linear_response(m, c, r=1.0, samples=samples)


def _margins(m: SampledModel, c: PIDTuning, g: DelayTF, h: float, stable: bool) -> tuple[float, float, float, float, float]:
    """(Ms, phase margin deg, gain margin, delay margin s, crossover rad/s) of L(e^(iwh))."""
    w, L = sampled_loop_response(c, g, h, m)
    ms = float(np.max(np.abs(1.0 / (1.0 + L)))) if stable else math.inf
    mag = np.abs(L)
    ph = np.unwrap(np.angle(L))
    # the low-frequency phase is -90 deg per integrator of the loop (minus 180 for a
    # negative loop gain): take the branch of the unwrapped phase that starts there
    n_int = (1 if math.isfinite(c.Ti) else 0) + g.integrators
    expect = -math.pi / 2 * n_int + (-math.pi if c.Kc * g.static_gain < 0 else 0.0)
    ph = ph + 2.0 * math.pi * round((expect - ph[0]) / (2.0 * math.pi))
    pm, wc = math.inf, math.nan
    lg = np.log(mag)
    for i in np.nonzero(np.sign(lg[:-1]) * np.sign(lg[1:]) < 0)[0]:
        f = lg[i] / (lg[i] - lg[i + 1])
        x = w[i] * (w[i + 1] / w[i]) ** f
        p = ph[i] + f * (ph[i + 1] - ph[i])
        marg = (math.degrees(p) + 360.0) % 360.0 - 180.0
        if marg < pm:
            pm, wc = marg, x
    am = math.inf
    k = np.floor((ph + math.pi) / (2.0 * math.pi))
    for i in np.nonzero(np.diff(k) != 0)[0]:
        if mag[i] > 1e-4:
            am = min(am, 1.0 / float(0.5 * (mag[i] + mag[i + 1])))
    lm = math.radians(pm) / wc if math.isfinite(pm) and wc > 0 else math.inf
    return ms, pm, am, lm, wc


def _horizon(c: PIDTuning, wc: float, h: float) -> int:
    t = 40.0 / wc if math.isfinite(wc) and wc > 0 else 600.0
    t = max(t, 3.0 * (c.Ti if math.isfinite(c.Ti) else 0.0), 40.0 * h)
    return min(MAX_SAMPLES, int(math.ceil(t / h)) + 1)


def evaluate_sampled(c: PIDTuning, g: DelayTF, h: float, *, u0: float | None = 0.5, setpoint: bool = True,
                     tr: float = TR_DEFAULT, model: SampledModel | None = None) -> SampledEvaluation:
    """All figures of `c` on `g` sampled at h (see the module); u0 = None skips the
    limit check (no operating point)."""
    m = model or sample(g, h)
    rate = slowest_rate(closed_loop_poles(m, c, h), h)
    stable = rate < 0.0
    ms, pm, am, lm, wc = _margins(m, c, g, h, stable)
    d = load_size(g)
    nan = math.nan
    if not stable:
        return SampledEvaluation(Evaluation(math.inf, pm, am, lm, wc, nan, nan, nan, d, nan, None, False, h),
                                 None)
    n = _horizon(c, wc, h)
    for _ in range(3):  # until the load response has died out
        load = linear_response(m, c, d=d, samples=n)
        tail = np.abs(load.y[int(0.9 * n):])
        if tail.max() <= 1e-3 * max(float(np.abs(load.y).max()), 1e-300) or n >= MAX_SAMPLES:
            break
        n = min(MAX_SAMPLES, 2 * n)
    e = np.abs(load.y)
    iae = float(np.sum(e) * h)
    u_over = float(np.max(np.abs(load.u)) / abs(d) - 1.0)
    overshoot, settling = nan, None
    if setpoint:
        sp = step_figures(linear_response(m, c, r=1.0, samples=n), (-math.inf, math.inf), h)
        overshoot, settling = sp.overshoot_pct, sp.settling
    ev = Evaluation(ms, pm, am, lm, wc, iae, float(e.max()), max(u_over, 0.0), d, overshoot, settling, True, h)
    check = None
    if u0 is not None:
        lim = (-u0, 1.0 - u0)
        ref = step_figures(simulate(m, c, r=STEP, samples=n, limits=lim, tr=tr), lim, h)
        # the load is answered by u = -d: towards the side of the range with more room
        dl = -STEP if u0 < 0.5 else STEP
        ld = step_figures(simulate(m, c, d=dl, samples=n, limits=lim, tr=tr), lim, h)
        check = LimitCheck(u0, ref, ld)
    return SampledEvaluation(ev, check)
