"""The one zero-order-hold integrator of every plant: adaptive Dormand-Prince 5(4).

A step holds the inputs over dt and integrates dx/dt = f(x) to a local error
tolerance, whatever dt, with the levels projected onto [lo, hi] after each accepted
sub-step (a full tank spills, an empty one stays empty); the sub-step shrinks where
a flow law bends (a tank running dry, a tank reaching its brim) until the error
estimate meets the tolerance.

Two forms of the same method, tableau, step control and projection:
:func:`dopri_advance` for a state of any size, and :func:`dopri_advance4`, the
four-level form the quadruple tank's sample runs, written out level by level in
plain floats because the simulator's sample is mostly this function.  The stage sums
of both are the same operations in the same order as ``sum(a[j] * k[j][i] for j)``,
so both give the numbers of the loop form bit for bit.
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

from quadtank_tui.core.plants.common import PlantError

Rhs = Callable[[Sequence[float]], Sequence[float]]
Levels = tuple[float, float, float, float]
#: dx/dt of a four-level state, the levels as four arguments.
Rhs4 = Callable[[float, float, float, float], Levels]

# Dormand-Prince 5(4) tableau (Hairer, Norsett & Wanner, Table 5.2).
C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
B = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0)
E = (  # b - b_hat: the embedded error estimate
    71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40,
)

# The tableau's entries by name, for the stage sums written out below.
_A21 = A[1][0]
_A31, _A32 = A[2]
_A41, _A42, _A43 = A[3]
_A51, _A52, _A53, _A54 = A[4]
_A61, _A62, _A63, _A64, _A65 = A[5]
_A71, _A72, _A73, _A74, _A75, _A76 = A[6]
_B1, _B2, _B3, _B4, _B5, _B6, _B7 = B
_E1, _E2, _E3, _E4, _E5, _E6, _E7 = E

#: Smallest sub-step, s: accepted whatever its error estimate, so no input can make a
#: step loop forever.
MIN_STEP = 1e-9


def check_step(dt: float) -> None:
    """PlantError unless dt is a finite number of seconds >= 0."""
    if dt < 0 or not math.isfinite(dt):
        raise PlantError(f"step length must be a finite number >= 0 s, got {dt}")


def _clip(y: Sequence[float], lo: Sequence[float], hi: Sequence[float]) -> list[float]:
    return [lo[i] if y[i] < lo[i] else (hi[i] if y[i] > hi[i] else y[i]) for i in range(len(y))]


def _step(f: Rhs, y: list[float], k0: Sequence[float], step: float, rtol: float, atol: float
          ) -> tuple[list[float], float]:
    """One Dormand-Prince step of `step` s from y: the 5th-order solution and its
    error estimate scaled by the tolerance (<= 1: accepted)."""
    r = range(len(y))
    k1 = f([y[i] + step * (_A21 * k0[i]) for i in r])
    k2 = f([y[i] + step * (_A31 * k0[i] + _A32 * k1[i]) for i in r])
    k3 = f([y[i] + step * (_A41 * k0[i] + _A42 * k1[i] + _A43 * k2[i]) for i in r])
    k4 = f([y[i] + step * (_A51 * k0[i] + _A52 * k1[i] + _A53 * k2[i] + _A54 * k3[i]) for i in r])
    k5 = f([y[i] + step * (_A61 * k0[i] + _A62 * k1[i] + _A63 * k2[i] + _A64 * k3[i] + _A65 * k4[i])
            for i in r])
    k6 = f([y[i] + step * (_A71 * k0[i] + _A72 * k1[i] + _A73 * k2[i] + _A74 * k3[i] + _A75 * k4[i]
                           + _A76 * k5[i]) for i in r])
    y_new = [y[i] + step * (_B1 * k0[i] + _B2 * k1[i] + _B3 * k2[i] + _B4 * k3[i] + _B5 * k4[i]
                            + _B6 * k5[i] + _B7 * k6[i]) for i in r]
    err = 0.0
    for i in r:
        e = step * (_E1 * k0[i] + _E2 * k1[i] + _E3 * k2[i] + _E4 * k3[i] + _E5 * k4[i]
                    + _E6 * k5[i] + _E7 * k6[i])
        err = max(err, abs(e) / (atol + rtol * max(abs(y[i]), abs(y_new[i]))))
    return y_new, err


def dopri_advance(f: Rhs, x: Sequence[float], dt: float, lo: Sequence[float], hi: Sequence[float],
                  *, rtol: float, atol: float) -> tuple[float, ...]:
    """x(dt) of dx/dt = f(x), integrated to (rtol, atol) and kept in [lo, hi].

    Parameters
    ----------
    f : the right-hand side with the inputs held, state units per second
    x : the state at the start, state units
    dt : the step, s (>= 0)
    lo, hi : the bounds of each state (a tank's floor and brim)
    rtol, atol : the local error tolerance, relative and in state units

    Returns
    -------
    The state after dt seconds, projected onto [lo, hi].
    """
    check_step(dt)
    y = _clip([float(v) for v in x], lo, hi)
    if dt == 0.0:
        return tuple(y)
    t = 0.0
    step = min(dt, 1.0)
    k = [list(f(y))]
    while t < dt:
        last = t + step >= dt
        if last:
            step = dt - t
        y_new, err = _step(f, y, k[0], step, rtol, atol)
        if err <= 1.0 or step <= MIN_STEP:
            t = dt if last else t + step
            y = _clip(y_new, lo, hi)
            k = [list(f(y))]
            factor = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
        else:
            factor = max(0.1, 0.9 * err ** -0.2)
        step = max(step * factor, MIN_STEP)
    return tuple(y)


def dopri_advance4(f: Rhs4, y: Levels, k0: Levels, dt: float, hmax: float, *, rtol: float, atol: float
                   ) -> tuple[Levels, bool, Levels]:
    """Four levels after dt > 0 seconds, each kept in [0, hmax]: the method of
    :func:`dopri_advance` written out level by level.

    Parameters
    ----------
    f : dh/dt with the inputs held, cm/s
    y : the levels at the start, already in [0, hmax], cm
    k0 : f(y), the slope there, cm/s
    dt : the step, s (> 0)
    hmax : the brim of every tank, cm
    rtol, atol : the local error tolerance, relative and in cm

    Returns
    -------
    (levels, smooth, slope): the levels after dt; whether the last sub-step needed no
    projection, and then `slope` is f at those levels (the last stage: First Same As
    Last), which the next step from there may take as its k0.
    """
    y1, y2, y3, y4 = y
    a1, a2, a3, a4 = k0  # f(t, y) at the start of the sub-step
    t = 0.0
    step = min(dt, 1.0)
    smooth = False
    while t < dt:
        if t + step >= dt:
            step = dt - t
            last = True
        else:
            last = False
        # One Dormand-Prince step: stages b..j, the 5th-order solution n, the error e.
        b1, b2, b3, b4 = f(y1 + step * (_A21 * a1), y2 + step * (_A21 * a2),
                           y3 + step * (_A21 * a3), y4 + step * (_A21 * a4))
        c1, c2, c3, c4 = f(y1 + step * (_A31 * a1 + _A32 * b1), y2 + step * (_A31 * a2 + _A32 * b2),
                           y3 + step * (_A31 * a3 + _A32 * b3), y4 + step * (_A31 * a4 + _A32 * b4))
        d1, d2, d3, d4 = f(y1 + step * (_A41 * a1 + _A42 * b1 + _A43 * c1),
                           y2 + step * (_A41 * a2 + _A42 * b2 + _A43 * c2),
                           y3 + step * (_A41 * a3 + _A42 * b3 + _A43 * c3),
                           y4 + step * (_A41 * a4 + _A42 * b4 + _A43 * c4))
        e1, e2, e3, e4 = f(y1 + step * (_A51 * a1 + _A52 * b1 + _A53 * c1 + _A54 * d1),
                           y2 + step * (_A51 * a2 + _A52 * b2 + _A53 * c2 + _A54 * d2),
                           y3 + step * (_A51 * a3 + _A52 * b3 + _A53 * c3 + _A54 * d3),
                           y4 + step * (_A51 * a4 + _A52 * b4 + _A53 * c4 + _A54 * d4))
        g1, g2, g3, g4 = f(y1 + step * (_A61 * a1 + _A62 * b1 + _A63 * c1 + _A64 * d1 + _A65 * e1),
                           y2 + step * (_A61 * a2 + _A62 * b2 + _A63 * c2 + _A64 * d2 + _A65 * e2),
                           y3 + step * (_A61 * a3 + _A62 * b3 + _A63 * c3 + _A64 * d3 + _A65 * e3),
                           y4 + step * (_A61 * a4 + _A62 * b4 + _A63 * c4 + _A64 * d4 + _A65 * e4))
        j1, j2, j3, j4 = f(y1 + step * (_A71 * a1 + _A72 * b1 + _A73 * c1 + _A74 * d1 + _A75 * e1 + _A76 * g1),
                           y2 + step * (_A71 * a2 + _A72 * b2 + _A73 * c2 + _A74 * d2 + _A75 * e2 + _A76 * g2),
                           y3 + step * (_A71 * a3 + _A72 * b3 + _A73 * c3 + _A74 * d3 + _A75 * e3 + _A76 * g3),
                           y4 + step * (_A71 * a4 + _A72 * b4 + _A73 * c4 + _A74 * d4 + _A75 * e4 + _A76 * g4))
        n1 = y1 + step * (_B1 * a1 + _B2 * b1 + _B3 * c1 + _B4 * d1 + _B5 * e1 + _B6 * g1 + _B7 * j1)
        n2 = y2 + step * (_B1 * a2 + _B2 * b2 + _B3 * c2 + _B4 * d2 + _B5 * e2 + _B6 * g2 + _B7 * j2)
        n3 = y3 + step * (_B1 * a3 + _B2 * b3 + _B3 * c3 + _B4 * d3 + _B5 * e3 + _B6 * g3 + _B7 * j3)
        n4 = y4 + step * (_B1 * a4 + _B2 * b4 + _B3 * c4 + _B4 * d4 + _B5 * e4 + _B6 * g4 + _B7 * j4)
        # The error estimate per level, scaled by atol + rtol max(|y|, |n|); err is the
        # largest, in order (max: a later one replaces only if larger).
        s1 = step * (_E1 * a1 + _E2 * b1 + _E3 * c1 + _E4 * d1 + _E5 * e1 + _E6 * g1 + _E7 * j1)
        s2 = step * (_E1 * a2 + _E2 * b2 + _E3 * c2 + _E4 * d2 + _E5 * e2 + _E6 * g2 + _E7 * j2)
        s3 = step * (_E1 * a3 + _E2 * b3 + _E3 * c3 + _E4 * d3 + _E5 * e3 + _E6 * g3 + _E7 * j3)
        s4 = step * (_E1 * a4 + _E2 * b4 + _E3 * c4 + _E4 * d4 + _E5 * e4 + _E6 * g4 + _E7 * j4)
        err = max(0.0, abs(s1) / (atol + rtol * max(abs(y1), abs(n1))), abs(s2) / (atol + rtol * max(abs(y2), abs(n2))),
                  abs(s3) / (atol + rtol * max(abs(y3), abs(n3))), abs(s4) / (atol + rtol * max(abs(y4), abs(n4))))
        if err <= 1.0 or step <= MIN_STEP:
            y1 = 0.0 if n1 < 0.0 else (hmax if n1 > hmax else n1)
            y2 = 0.0 if n2 < 0.0 else (hmax if n2 > hmax else n2)
            y3 = 0.0 if n3 < 0.0 else (hmax if n3 > hmax else n3)
            y4 = 0.0 if n4 < 0.0 else (hmax if n4 > hmax else n4)
            # Not projected: the levels are n, where the last stage j was taken (its
            # sum is n's: b7 = 0), so j is the slope there (First Same As Last).
            smooth = 0.0 <= n1 <= hmax and 0.0 <= n2 <= hmax and 0.0 <= n3 <= hmax and 0.0 <= n4 <= hmax
            if last:
                break
            t += step
            a1, a2, a3, a4 = (j1, j2, j3, j4) if smooth else f(y1, y2, y3, y4)
            factor = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
        else:
            factor = max(0.1, 0.9 * err ** -0.2)
        step = max(step * factor, MIN_STEP)
    return (y1, y2, y3, y4), smooth, (j1, j2, j3, j4)
