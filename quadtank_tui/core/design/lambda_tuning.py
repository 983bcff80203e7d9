"""Lambda tuning of a PI controller (Andersson 3.3) and the first-order model it needs.

Self-regulating K e^(-sL)/(sT + 1):  Ti = T,  Kc = T / (K (lambda + L)).
Integrating    Kv e^(-sL)/s:         Ti = 2 lambda + L,  Kc = Ti / (Kv (lambda + L)^2).

Lambda tuning is defined on those two structures only.  A richer model is first
reduced, and the reduction is reported with the design:

* self-regulating: the least-squares fit of K e^(-sL)/(sT+1), K fixed at G(0), to
  the model's unit-step response.  This is how Andersson's first-order models
  relate to his higher-order ones (his fit was on the data): for process 1,
  1.6592 e^(-2.4s)/(1.07s+1)^3 gives T = 2.14, L = 3.60 (printed: 2.13, 3.60).
* integrating Kv e^(-sL)/(s (sT1+1)...): the ramp asymptote, Kv e^(-s(L + sum Ti
  - sum Tz))/s, which has the same late response exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import step

from quadtank_tui.core.delaytf import DelayTF
from quadtank_tui.core.design.pid_tuning import PIDTuning, DesignError


@dataclass(frozen=True)
class FirstOrder:
    """K e^(-sL)/(sT+1) (integrating=False) or K e^(-sL)/s (integrating=True, T = 0)."""

    K: float
    T: float
    L: float
    integrating: bool
    how: str  # "exact", "step-response fit", "ramp asymptote"

    def model(self) -> DelayTF:
        den = (1.0, 0.0) if self.integrating else (self.T, 1.0)
        return DelayTF((self.K,), den, self.L)

    def __str__(self) -> str:
        if self.integrating:
            return f"{self.K:.4g}*exp(-{self.L:.4g}*s)/s ({self.how})"
        return f"{self.K:.4g}*exp(-{self.L:.4g}*s)/({self.T:.4g}*s+1) ({self.how})"


def _check_poles(g: DelayTF) -> None:
    poles = g.poles()
    if np.any(poles.real > 1e-12):
        bad = ", ".join(f"{p:.4g}" for p in poles[poles.real > 1e-12])
        raise DesignError(f"lambda tuning needs a stable or integrating model; this one has a "
                          f"pole in the right half-plane ({bad} 1/s)")
    if g.integrators > 1:
        raise DesignError(f"lambda tuning handles one integrator at most; the model has {g.integrators}")
    if np.any((np.abs(poles.real) <= 1e-12) & (np.abs(poles) > 1e-12)):
        raise DesignError("lambda tuning needs a model without undamped oscillating poles")


def first_order(g: DelayTF) -> FirstOrder:
    """The first-order (or pure integrator) model lambda tuning is applied to."""
    _check_poles(g)
    k = g.static_gain
    if k == 0.0:
        raise DesignError("the model has zero static gain: lambda tuning has nothing to act on")
    num, den = np.array(g.num), np.array(g.den)
    if g.integrators == 1:
        rest = den[:-1]
        if len(num) == 1 and len(rest) == 1:
            return FirstOrder(k, 0.0, g.delay, True, "exact")
        # ramp asymptote Kv (t - L - D'(0)/D(0) + N'(0)/N(0)) of Kv N/(s D) e^-sL
        lags = float(rest[-2] / rest[-1]) if len(rest) > 1 else 0.0
        leads = float(num[-2] / num[-1]) if len(num) > 1 else 0.0
        L = g.delay + lags - leads
        if L < 0.0:
            raise DesignError("the model's zeros lead its lags: no delay-integrator approximation")
        return FirstOrder(k, 0.0, L, True, "ramp asymptote")
    if len(num) == 1 and len(den) == 2:
        return FirstOrder(k, den[0] / den[1], g.delay, False, "exact")
    return _fit_step(g, k)


def _fit_step(g: DelayTF, k: float) -> FirstOrder:
    """Least-squares FOPDT fit, K fixed, to the unit-step response of g."""
    slow = sum(1.0 / abs(p) for p in g.poles())
    t = np.linspace(0.0, 10.0 * slow, 3000)
    _, y = step((list(g.num), list(g.den)), T=t)
    t = t + g.delay

    def residual(p: np.ndarray) -> np.ndarray:
        T, L = p
        return np.where(t > L, k * (1.0 - np.exp(-(t - L) / T)), 0.0) - y

    fit = least_squares(residual, [slow, g.delay + 0.1 * slow],
                        bounds=([1e-9 * slow, 0.0], [np.inf, np.inf]))
    T, L = (float(x) for x in fit.x)
    return FirstOrder(k, T, L, False, "step-response fit")


def lambda_for_tau(fo: FirstOrder, tau: float) -> float:
    """Andersson's eq. (1): lambda = tau max(L, T) (self-regulating)."""
    return tau * max(fo.L, fo.T)


#: default lambda of a self-regulating loop: a fifth of max(L, T) of its first-order model
#: (a 0.1 step then settles in 138 s at P- with no overshoot and the pumps clear of their
#: limits; T/3: 207 s; T/8: 90 s with Kc = 3).
LAMBDA_FRACTION = 1.0 / 5.0


def default_lambda(fo: FirstOrder) -> float:
    """The one default lambda (s) the 2x2 design and the Design screen propose:
    max(L, T)/5; an integrating loop twice its delay (1 s without one)."""
    if fo.integrating:
        return 2.0 * (fo.L if fo.L > 0.0 else 1.0)
    return LAMBDA_FRACTION * max(fo.L, fo.T)


def lambda_pi(fo: FirstOrder, lam: float, h: float = 0.0) -> PIDTuning:
    """The lambda-tuned PI for the closed-loop time constant (or load time) `lam` s.

    h > 0 (a loop sampled at h s): the zero-order hold delays the input by h/2 on
    average, so the rule sees the dead time L + h/2 (the standard approximation;
    the exact sampled evaluation, core.design.sampled_eval, then checks the result)."""
    if not math.isfinite(lam) or lam <= 0.0:
        raise DesignError(f"lambda must be a time > 0 s, got {lam:g}")
    L = fo.L + 0.5 * h
    if fo.integrating:
        ti = 2.0 * lam + L
        return PIDTuning(ti / (fo.K * (lam + L) ** 2), ti)
    return PIDTuning(fo.T / (fo.K * (lam + L)), fo.T)
