"""PID element (Astrom & Hagglund; Nunes 1998, 5.5).

    U = K [ b R - Y + 1/(s Ti) (R - Y) + s Td / (1 + s Td / N) (a R - Y) ]

The thesis's sentence on discretization reads "forward and backward differences to
approximate the derivative and the integral parts, respectively" and cites Astrom &
Hagglund, whose algorithm does the opposite: forward differences for the integral
(the integral state for the next sample is known after this one, which is what makes
the two-phase compute/update and anti-windup possible) and backward differences for
the derivative (stable for every Td/N and h).  We follow the cited algorithm.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from quadtank_tui.core.ranges import ParameterError, check_range, check_sampling_time


@dataclass(frozen=True)
class PIDParams:
    """One PID element's settings (keys as in the `.par` CONTROLLER sections).

    K : gain, normalized input per normalized error (may be negative, as at P+)
    Ti : integral time, s (> 0)
    Td : derivative time, s (>= 0)
    Tr : anti-windup tracking (reset) time, s (> 0)
    N : maximum derivative gain (> 0)
    a, b : setpoint weights of the D and P parts, [0, 1]
    integral, derivative : the I and D parts switched on
    """

    K: float = 1.0
    Ti: float = 30.0
    Td: float = 0.0
    Tr: float = 1.0
    N: float = 10.0
    a: float = 0.0
    b: float = 1.0
    integral: bool = True
    derivative: bool = False

    def __post_init__(self) -> None:
        check_range("K", self.K, -1e3, 1e3)
        check_range("Ti", self.Ti, 0.0, 1e6, lo_open=True)
        check_range("Td", self.Td, 0.0, 1e6)
        check_range("Tr", self.Tr, 0.0, 1e6, lo_open=True)
        check_range("N", self.N, 0.0, 1e3, lo_open=True)
        check_range("a", self.a, 0.0, 1.0)
        check_range("b", self.b, 0.0, 1.0)
        for name in ("integral", "derivative"):
            if not isinstance(getattr(self, name), bool):
                raise ParameterError("I" if name == "integral" else "D", "must be 0 or 1")


class PID:
    """One SISO PID element, Astrom & Hagglund's discrete algorithm, in two phases.

    Every sample the engine calls :meth:`compute` (pure: the unsaturated control
    value ``v`` for this sample), saturates and applies ``u``, then calls
    :meth:`update` with the applied ``u`` (Automatic) or :meth:`track` (Manual).
    Splitting the sample in two is what lets anti-windup see the *applied* input.

    Discretization at sampling time ``h`` (s), all signals normalized (1.0 = 10 V)::

        P(k)   = K (b r(k) - y(k))
        D(k)   = ad D(k-1) + bd [(a r(k) - y(k)) - (a r(k-1) - y(k-1))]
                 ad = Td / (Td + N h),  bd = K Td N / (Td + N h)   (backward difference)
        v(k)   = P(k) + I(k) + D(k)
        I(k+1) = I(k) + K h / Ti (r(k) - y(k)) + h / Tr (u(k) - v(k))   (forward difference)

    ``ad`` is the backward-difference image of the filter pole: ``1/ad = 1 + h N/Td``,
    i.e. a first-order lag of time constant ``Td/N``.  The derivative filter limits the
    high-frequency gain to ``K N``.

    The states are stored as the contributions ``I`` and ``D`` to ``v`` (not as a raw
    integral), so a change of ``K``, ``Ti`` or ``h`` changes only future increments and
    never makes ``v`` jump by itself.  With the integral part off, ``I`` is a constant
    bias (the "manual reset" of a P/PD controller): it is what absorbs a parameter
    change or carries the manual input at a Manual -> Automatic switch.

    ``anti_windup`` enables the back-calculation term; the controller matrix sets it
    only on the diagonal elements (Nunes 1998, 5.5), because an off-diagonal element
    does not own the input it contributes to.
    """

    def __init__(self, params: PIDParams, h: float, *, anti_windup: bool = True) -> None:
        check_sampling_time(h)
        self._p = params
        self._d_on = _derivative_on(params)
        self._h = float(h)
        self.anti_windup = anti_windup
        self._I = 0.0
        self._D = 0.0
        self._last: tuple[float, float] | None = None  # (r, y) of the previous sample

    # --- read-only views ------------------------------------------------------------

    @property
    def params(self) -> PIDParams:
        return self._p

    @property
    def h(self) -> float:
        """Sampling time, s."""
        return self._h

    @property
    def integral_state(self) -> float:
        """The integral (or, with I off, bias) contribution to v, normalized."""
        return self._I

    @property
    def derivative_state(self) -> float:
        """The filtered derivative contribution to v of the last committed sample."""
        return self._D

    # --- the algorithm --------------------------------------------------------------

    def _proportional(self, p: PIDParams, r: float, y: float) -> float:
        return p.K * (p.b * r - y)

    def _derivative(self, p: PIDParams, r: float, y: float) -> float:
        """D(k) from D(k-1); zero with the D part off, no kick on the first sample."""
        if not _derivative_on(p):
            return 0.0
        den = p.Td + p.N * self._h
        ad = p.Td / den
        bd = p.K * p.Td * p.N / den
        if self._last is None:
            return ad * self._D
        r0, y0 = self._last
        return ad * self._D + bd * ((p.a * r - y) - (p.a * r0 - y0))

    def compute(self, r: float, y: float) -> float:
        """Unsaturated control value v for this sample (no state change; idempotent)."""
        p = self._p
        D = self._derivative(p, r, y) if self._d_on else 0.0  # (a PI's every sample: no call)
        return p.K * (p.b * r - y) + self._I + D  # P + I + D, as _proportional forms P

    def update(self, r: float, y: float, u_applied: float, v: float | None = None) -> None:
        """Commit the sample after ``u_applied`` (the saturated input) went out.

        Integrates the error (forward difference) and, if ``anti_windup``, pulls the
        integral towards the applied input with time constant Tr: the term
        ``h/Tr (u - v)`` is zero while unsaturated and unwinds I while saturated.
        ``v``: this sample's :meth:`compute`, if the caller has it (the same number).
        """
        p = self._p
        D = self._derivative(p, r, y) if self._d_on else 0.0
        if v is None:
            v = self._proportional(p, r, y) + self._I + D
        if p.integral:
            self._I += p.K * self._h / p.Ti * (r - y)
            if self.anti_windup:
                self._I += self._h / p.Tr * (u_applied - v)
        self._D = D
        self._last = (r, y)

    def track(self, r: float, y: float, u_applied: float) -> None:
        """Manual mode: follow the applied input so Automatic starts from it.

        Sets I so that this sample's v equals ``u_applied`` exactly; the first
        Automatic sample then differs from it only by the change of P and D, i.e. by
        what the error itself does.
        """
        p = self._p
        D = self._derivative(p, r, y)
        self._I = u_applied - self._proportional(p, r, y) - D
        self._D = D
        self._last = (r, y)

    # --- changes while running --------------------------------------------------------

    def set_params(self, params: PIDParams) -> None:
        """New parameters without a bump in v.

        The integral (or bias) state takes up whatever the new law would change at the
        last sample's (r, y): the next v then differs from the last one only by what the
        new r and y cause.  A derivative part switched off drops its state (taken up
        the same way); switched on, it starts from rest.
        """
        self._absorb(lambda: self._set(params))

    def set_sampling_time(self, h: float) -> None:
        """New sampling time, s.  I and D are stored as contributions to v; the
        derivative filter's new coefficient is absorbed like a parameter change."""
        h = check_sampling_time(h)
        self._absorb(lambda: setattr(self, "_h", h))

    def _set(self, params: PIDParams) -> None:
        self._p = params
        self._d_on = _derivative_on(params)
        if not self._d_on:
            self._D = 0.0

    def _absorb(self, change: Callable[[], None]) -> None:
        """Apply `change`, keeping compute(r, y) at the last (r, y) where it was."""
        if self._last is None:
            change()
            return
        before = self.compute(*self._last)
        change()
        self._I += before - self.compute(*self._last)

    def reset(self) -> None:
        """Forget all states (I, D and the previous sample)."""
        self._I = 0.0
        self._D = 0.0
        self._last = None


def _derivative_on(p: PIDParams) -> bool:
    """Whether the D part acts (switched on, with a derivative time)."""
    return p.derivative and p.Td != 0.0
