"""General transfer-function element (Nunes 1998, 5.5).

    U(s) = (s0 s^n + s1 s^(n-1) + ... + sn) / (s^n + r1 s^(n-1) + ... + rn) E(s),  n = 0..4
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from quadtank_tui.core.ranges import ParameterError, check_number, check_sampling_time

MAX_DEGREE = 4


@dataclass(frozen=True)
class GeneralParams:
    """Degree n and the coefficients; s holds s0..s4, r holds r1..r4 (only the
    first n + 1 of s and n of r are used)."""

    degree: int = 0
    s: tuple[float, float, float, float, float] = (1.0, 0.0, 0.0, 0.0, 0.0)
    r: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if isinstance(self.degree, bool) or self.degree not in range(MAX_DEGREE + 1):
            raise ParameterError("Degree", f"must be an integer 0..{MAX_DEGREE}, got {self.degree!r}")
        if len(self.s) != 5 or len(self.r) != 4:
            raise ParameterError("s0", "five numerator (s0..s4) and four denominator (r1..r4) coefficients")
        for i, x in enumerate(self.s):
            check_number(f"s{i}", x)
        for i, x in enumerate(self.r):
            check_number(f"r{i + 1}", x)

    @property
    def numerator(self) -> tuple[float, ...]:
        """s0..sn, highest power first."""
        return tuple(self.s[: self.degree + 1])

    @property
    def denominator(self) -> tuple[float, ...]:
        """1, r1..rn, highest power first (monic)."""
        return (1.0, *self.r[: self.degree])


def tustin(num: Sequence[float], den: Sequence[float], h: float) -> tuple[np.ndarray, np.ndarray]:
    """Discretize a proper C(s) = num/den with Tustin, s = (2/h)(z - 1)/(z + 1).

    Both polynomials are padded to degree n = len(den) - 1 and every s^i term becomes
    (2/h)^i (z - 1)^i (z + 1)^(n - i); the result is normalized so the z-denominator is
    monic.  Same numbers as ``scipy.signal.cont2discrete(..., method="bilinear")``.
    A pole at s = 2/h maps to z = infinity and cannot be discretized: refused.
    """
    n = len(den) - 1
    numc = np.concatenate([np.zeros(n + 1 - len(num)), np.asarray(num, dtype=float)])
    denc = np.asarray(den, dtype=float)
    c = 2.0 / h
    numd = np.zeros(n + 1)
    dend = np.zeros(n + 1)
    for k in range(n + 1):  # coefficient of s^(n - k)
        power = n - k
        term = c**power * np.polymul(
            np.poly(np.ones(power)) if power else np.ones(1),
            np.poly(-np.ones(n - power)) if n - power else np.ones(1),
        )
        numd += numc[k] * term
        dend += denc[k] * term
    if abs(dend[0]) <= 1e-12 * max(1.0, float(np.abs(dend).max())):
        raise ParameterError(
            "r1",
            f"a pole at s = 2/h = {c:g} 1/s cannot be discretized with Tustin at sampling "
            f"time {h:g} s; move the pole or change the sampling time",
        )
    return numd / dend[0], dend / dend[0]


def realize(numd: np.ndarray, dend: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Observer canonical form (direct form II transposed) of a monic discrete H(z).

    x(k+1) = Phi x(k) + Gam e(k),  u(k) = C x(k) + D e(k), with C = [1, 0, ..., 0].
    This form is always observable, which is what the bumpless re-initialization in
    :meth:`General._matched_state` needs.
    """
    n = len(dend) - 1
    b0 = float(numd[0])
    Phi = np.zeros((n, n))
    Gam = numd[1:] - dend[1:] * b0
    C = np.zeros(n)
    if n:
        Phi[:, 0] = -dend[1:]
        Phi[: n - 1, 1:] = np.eye(n - 1)
        C[0] = 1.0
    return Phi, Gam, C, b0


Realization = tuple[np.ndarray, np.ndarray, np.ndarray, float]


@functools.lru_cache(maxsize=256)
def realization(num: tuple[float, ...], den: tuple[float, ...], h: float) -> Realization:
    """realize(*tustin(num, den, h)), once per element and sampling time: every
    engine and every installation builds four elements, mostly the default gain, and
    the discretization is numpy work worth doing once.  The arrays are read-only, since
    the elements holding them share them.  The check that an element can be
    discretized at all (ParameterError, never cached) is this call too, so the
    element built after it finds its realization made."""
    Phi, Gam, C, D = realize(*tustin(num, den, h))
    for a in (Phi, Gam, C):
        a.setflags(write=False)
    return Phi, Gam, C, D


class General:
    """One SISO General element: C(s) of degree 0..4, Tustin-discretized, stepped as a
    discrete state-space system every sample (all signals normalized, h in seconds).

    Two phases per sample like :class:`~quadtank_tui.core.controllers.pid.PID`: :meth:`compute`
    (pure) gives u(k) = C x(k) + D e(k); :meth:`update` commits x(k+1) = Phi x(k) + Gam
    e(k) once the input went out.  In Manual mode :meth:`track` keeps the state
    matched to the applied input.  General elements have no anti-windup: the original
    put it on the diagonal PID elements only (Nunes 1998, 5.5).

    Bumpless changes (coefficients, h, Manual -> Automatic): the new realization's
    state is chosen so the element is *at rest at the last output*: with the input held
    at the last error e0, its output would stay at the last output u0 for n samples,
    ``C Phi^m x + sum_{i<m} C Phi^(m-1-i) Gam e0 + D e0 = u0`` for m = 0..n-1.  The
    observability matrix of the observer form is unit triangular, so this n x n system
    always has one solution.  Continuity is exact (m = 0): the next output differs from
    u0 only by D (e(k+1) - e0), the error's own effect; "at rest" (m >= 1) means no
    transient is started by the change, any drift afterwards is the controller's own
    dynamics.  A degree-0 element (a pure gain) has no state, so a constant bias takes
    up the difference, like the manual reset of a P controller.
    """

    def __init__(self, params: GeneralParams, h: float) -> None:
        self._h = check_sampling_time(h)
        self._p = params
        self._Phi, self._Gam, self._C, self._D = realization(params.numerator, params.denominator, self._h)
        self._x: np.ndarray = np.zeros(params.degree)
        self._bias = 0.0
        self._last: tuple[float, float] | None = None  # (e, u) of the previous sample

    @property
    def params(self) -> GeneralParams:
        return self._p

    @property
    def h(self) -> float:
        return self._h

    @property
    def state(self) -> tuple[float, ...]:
        """The discrete state x (observer canonical form), normalized."""
        return tuple(float(v) for v in self._x)

    def discrete(self) -> tuple[np.ndarray, np.ndarray]:
        """(numerator, denominator) of the discretized H(z), highest power first."""
        return tustin(self._p.numerator, self._p.denominator, self._h)

    def compute(self, e: float) -> float:
        """u(k) for error e(k), normalized (no state change; idempotent)."""
        return float(self._C @ self._x) + self._D * e + self._bias

    def update(self, e: float) -> None:
        """Commit the sample: x(k+1) = Phi x(k) + Gam e(k)."""
        u = self.compute(e)
        self._x = self._Phi @ self._x + self._Gam * e
        self._last = (e, u)

    def track(self, e: float, u_applied: float) -> None:
        """Manual mode: put the element at rest at the applied input, so the first
        Automatic sample moves only by D times the error's change."""
        self._last = (e, u_applied)
        self._rematch(e, u_applied)

    def set_params(self, params: GeneralParams) -> None:
        """New coefficients (and degree) without a jump in u."""
        discrete = realization(params.numerator, params.denominator, self._h)
        self._p = params
        self._Phi, self._Gam, self._C, self._D = discrete
        self._after_change()

    def set_sampling_time(self, h: float) -> None:
        """Re-discretize at the new sampling time (s) without a jump in u."""
        h = check_sampling_time(h)
        discrete = realization(self._p.numerator, self._p.denominator, h)
        self._h = h
        self._Phi, self._Gam, self._C, self._D = discrete
        self._after_change()

    def reset(self) -> None:
        """Zero state, no bias, no memory of the previous sample."""
        self._x = np.zeros(self._p.degree)
        self._bias = 0.0
        self._last = None

    def _after_change(self) -> None:
        if self._last is None:
            self.reset()
            return
        self._rematch(*self._last)

    def _rematch(self, e0: float, u0: float) -> None:
        """Set (x, bias), the state for the next sample, at rest at the last output.

        Solves the n rest conditions of the class docstring for x = x(k+1), with
        (e0, u0) the last sample's error and output.
        """
        n = self._p.degree
        if n == 0:
            self._x = np.zeros(0)
            self._bias = u0 - self._D * e0
            return
        self._bias = 0.0
        O = np.empty((n, n))
        rhs = np.empty(n)
        row = self._C.copy()
        forced = self._D * e0
        for m in range(n):
            O[m] = row
            rhs[m] = u0 - forced
            forced += float(row @ self._Gam) * e0
            row = row @ self._Phi
        self._x = np.linalg.solve(O, rhs)
