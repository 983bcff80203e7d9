"""The running state-feedback tracking controller and its smart integrator (3.1-3.3).

Per sample, with w = x - x_e and e = r - C x (tracked outputs)::

    u = u_e + L2 x_a - L1 w                                          (3.1.7)

then the smart integrator (Desautel's Figure 12, generalized to several inputs):

1. tank-level saturation: while a level that input i fills is above its trigger (the
   top minus a margin), u_i is capped at U_ssmax_i, the voltage that holds that tank a
   little lower (3.2.2), and x_a is held;
2. pump saturation: u is clipped to [u_min, u_max] and x_a is corrected by the excess,
   x_a <- x_a - L3 (u_wanted - u_applied) (3.3);
3. otherwise the plain digital integrator, x_a <- x_a + e.

Desautel's Figure 12 enters the pump case at 0.95 U_max and then applies U_max; here
the case starts at the limit itself, so u is never pushed up to U_max by the rule.

`AntiWindup.PLAIN` keeps step 3 always (the pumps still clip): the integrator then winds
up while a limit holds the process, the comparison of his Figures 7-10.

Bumpless: `track` (Manual) and `redesign` choose x_a so that u is what was applied,
L2 x_a = u - u_e + L1 w (3.1.10: from empty tanks with u = 0 this is his
x_a[0] = -(u_e + L1 x_e) L2^-1).

L3 is given as a multiple k of L2^-1: x_a moves by -k L2^-1 (excess), so the integral
part of u is pulled back by k times the excess (k = 1: exactly to the limit).
Desautel's CTP value L3 = 10.5 is k = 10.5 * 0.13191 = 1.385.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Sequence

import numpy as np
import numpy.typing as npt

from quadtank_tui.core.controllers.statefb.placement import Design, PlacementError


class AntiWindup(str, Enum):
    """How x_a is updated while a limit holds the process."""

    SMART = "Smart"
    PLAIN = "Plain"


def u_ssmax(alpha: float, beta: float, level: float, g: float = 981.0) -> float:
    """Pump voltage that holds a tank fed by that pump alone at `level` (3.2.2).

    U_ssmax = alpha sqrt(2 g x_max) / beta; alpha is the outlet's coefficient (an outlet
    area, cm^2, per unit tank area), beta the pump's (cm/s per V)."""
    if level < 0:
        raise PlacementError(f"a level limit must be >= 0 cm, got {level:g}")
    return alpha * math.sqrt(2.0 * g * level) / beta


@dataclass(frozen=True)
class LevelLimit:
    """Tank-level saturation: while x[state] > trigger, input `pump` is capped at u_hold.

    u_hold should hold the tank somewhat below the trigger (Desautel: "x_max must be
    slightly less than the physical maximum ... avoids an infinite loop").
    """

    state: int
    pump: int
    trigger: float
    u_hold: float


@dataclass(frozen=True)
class Output:
    """One sample's controller output: applied u, the unlimited u and what limited it."""

    u: np.ndarray
    wanted: np.ndarray
    level_held: tuple[bool, ...]
    pump_limited: tuple[bool, ...]


class StateFeedback:
    """u = u_e + L2 x_a - L1 w with a smart (or plain) integrator, in physical units.

    Stepped in two phases like the PID matrix: ``out = output(r, x)``, apply
    ``out.u``, then ``update(r, x, out)`` (Automatic) or ``track(x, u)`` (Manual).
    """

    def __init__(
        self,
        d: Design,
        *,
        l3: float = 1.0,
        anti_windup: AntiWindup = AntiWindup.SMART,
        level_limits: Sequence[LevelLimit] = (),
    ) -> None:
        self._d = d
        self.l3 = _check_l3(l3)
        self.anti_windup = AntiWindup(anti_windup)
        self.level_limits = tuple(level_limits)
        for lim in self.level_limits:
            if not (0 <= lim.state < d.model.n and 0 <= lim.pump < d.model.m):
                raise PlacementError(f"level limit on state {lim.state}, pump {lim.pump}: no such state or pump")
        self.x_a = np.zeros(d.model.p)
        self._last_x = np.array(d.model.x_e, dtype=float)

    @property
    def design(self) -> Design:
        return self._d

    # --- one sample --------------------------------------------------------------------

    def output(self, r: npt.ArrayLike, x: npt.ArrayLike) -> Output:
        """The input for this sample (pure): 3.1.7, then the level and pump limits."""
        d, m = self._d, self._d.model
        xv = np.asarray(x, dtype=float)
        wanted = m.u_e + d.L2 @ self.x_a - d.L1 @ (xv - m.x_e)
        hi = m.u_max.copy()
        held = [False] * m.m
        for lim in self.level_limits:
            if xv[lim.state] > lim.trigger:
                hi[lim.pump] = min(hi[lim.pump], lim.u_hold)
                held[lim.pump] = held[lim.pump] or wanted[lim.pump] > lim.u_hold
        u = np.clip(wanted, m.u_min, hi)
        limited = tuple(bool(u[i] != wanted[i]) and not held[i] for i in range(m.m))
        return Output(u, wanted, tuple(held), limited)

    def update(self, r: npt.ArrayLike, x: npt.ArrayLike, out: Output,
               u_applied: npt.ArrayLike | None = None) -> None:
        """Automatic: advance x_a after `out` went out (u_applied if something else
        clipped it further, e.g. the DAQ's range)."""
        d = self._d
        xv = np.asarray(x, dtype=float)
        u = out.u if u_applied is None else np.asarray(u_applied, dtype=float)
        excess = out.wanted - u
        e = np.asarray(r, dtype=float) - d.model.C @ xv
        if self.anti_windup is AntiWindup.PLAIN or not np.any(np.abs(excess) > 1e-12):
            self.x_a = self.x_a + e
        elif any(out.level_held):
            pass  # held: the tank, not the controller, limits the process
        else:
            self.x_a = self.x_a - self.l3 * _solve(d.L2, excess)
        self._last_x = xv

    def track(self, x: npt.ArrayLike, u_applied: npt.ArrayLike) -> None:
        """Manual (or a start): x_a such that this sample's u equals `u_applied`."""
        d = self._d
        xv = np.asarray(x, dtype=float)
        v = np.asarray(u_applied, dtype=float) - d.model.u_e + d.L1 @ (xv - d.model.x_e)
        self.x_a = _solve(d.L2, v)
        self._last_x = xv

    def redesign(self, new: Design) -> None:
        """New gains or model between samples; u at the last state does not jump."""
        if (new.model.n, new.model.m, new.model.p) != (self._d.model.n, self._d.model.m, self._d.model.p):
            raise PlacementError("a redesign must keep the numbers of states, inputs and outputs")
        d = self._d
        u_now = d.model.u_e + d.L2 @ self.x_a - d.L1 @ (self._last_x - d.model.x_e)
        self._d = new
        self.track(self._last_x, u_now)

    def set_limits(self, *, l3: float | None = None, anti_windup: AntiWindup | None = None,
                   level_limits: Sequence[LevelLimit] | None = None) -> None:
        """Change the smart integrator's settings (no effect on u until a limit acts)."""
        if l3 is not None:
            self.l3 = _check_l3(l3)
        if anti_windup is not None:
            self.anti_windup = AntiWindup(anti_windup)
        if level_limits is not None:
            self.level_limits = tuple(level_limits)

    def reset(self) -> None:
        """Integrators to zero (the Controller Reset button)."""
        self.x_a = np.zeros(self._d.model.p)


def _check_l3(l3: float) -> float:
    if not (isinstance(l3, (int, float)) and math.isfinite(l3) and l3 >= 0):
        raise PlacementError(f"L3 must be a number >= 0, got {l3!r}")
    return float(l3)


def _solve(L2: np.ndarray, v: np.ndarray) -> np.ndarray:
    """x with L2 x = v (least squares when L2 is not square)."""
    if L2.shape[0] == L2.shape[1]:
        try:
            return np.linalg.solve(L2, v)
        except np.linalg.LinAlgError:
            pass
    return np.linalg.lstsq(L2, v, rcond=None)[0]
