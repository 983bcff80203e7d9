"""A plant's linearization: A, B, C, D about an operating point, and what follows.

Deviations: x - x0 in the plant's length unit, u - u0 in pump volts, y in sensor
volts.  The transfer matrix, poles and transmission zeros come from python-control
(no slycot needed); the zero-order-hold discretization is the exact matrix
exponential of [[A, B], [0, 0]] T (Desautel 3.1: Phi = e^{AT}, Gamma = int e^{As} ds B).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

if TYPE_CHECKING:
    import control


@dataclass(frozen=True, eq=False)
class LinearModel:
    """dx/dt = A x + B u, y = C x + D u about (x0, u0)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    x0: tuple[float, ...]
    u0: tuple[float, ...]
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]

    @classmethod
    def of(cls, A: Any, B: Any, C: Any, *, x0: Sequence[float], u0: Sequence[float],
           states: Sequence[str], inputs: Sequence[str], outputs: Sequence[str]) -> LinearModel:
        a, b, c = (np.array(m, dtype=float) for m in (A, B, C))
        return cls(a, b, c, np.zeros((c.shape[0], b.shape[1])), tuple(x0), tuple(u0),
                   tuple(states), tuple(inputs), tuple(outputs))

    def ss(self) -> control.StateSpace:
        """The python-control state-space object, signals named."""
        import control  # python-control and scipy load in a second: only when asked

        return control.ss(self.A, self.B, self.C, self.D, inputs=list(self.inputs),
                          outputs=list(self.outputs), states=list(self.states))

    def tf(self) -> control.TransferFunction:
        """The transfer matrix G(s) (outputs x inputs), V/V."""
        import control

        return control.ss2tf(self.ss())

    def select(self, outputs: Sequence[int]) -> LinearModel:
        """The same model with only some outputs (e.g. the controlled lower tank)."""
        idx = list(outputs)
        return LinearModel(self.A, self.B, self.C[idx], self.D[idx], self.x0, self.u0, self.states,
                           self.inputs, tuple(self.outputs[i] for i in idx))

    def poles(self) -> np.ndarray:
        """Eigenvalues of A, sorted by real part."""
        return np.array(sorted(np.linalg.eigvals(self.A), key=lambda z: (z.real, z.imag)))

    def zeros(self) -> np.ndarray:
        """Finite transmission zeros of a square model, sorted by real part: the finite
        generalized eigenvalues of the Rosenbrock pencil ([[A, B], [C, D]], [[I, 0], [0, 0]])."""
        m = self.B.shape[1]
        if self.C.shape[0] != m:
            raise ValueError(f"transmission zeros need as many outputs as inputs ({self.C.shape[0]} vs {m}); "
                             "select the controlled outputs first")
        return finite_zeros(self.A, self.B, self.C, self.D)

    def dcgain(self) -> np.ndarray:
        """G(0) = D - C A^-1 B (every plant here is stable, A invertible)."""
        return self.D - self.C @ np.linalg.solve(self.A, self.B)

    def freqresp(self, w: np.ndarray) -> np.ndarray:
        """G(jw) for each w, shape (len(w), outputs, inputs), evaluated from A, B, C, D."""
        n = self.A.shape[0]
        out = np.empty((len(w), self.C.shape[0], self.B.shape[1]), dtype=complex)
        eye = np.eye(n)
        for k, wk in enumerate(np.asarray(w, dtype=float)):
            out[k] = self.C @ np.linalg.solve(1j * wk * eye - self.A, self.B) + self.D
        return out

    def c2d(self, T: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Gamma) of the zero-order-hold discretization at sampling time T s."""
        if not T > 0:
            raise ValueError(f"sampling time must be > 0 s, got {T}")
        return zoh(self.A, self.B, T)


#: A zero this many times faster than the model's fastest pole is a zero at infinity
#: that rounding left finite.  The pencil's infinite eigenvalues come out as 1e14 or
#: so, their sign by the machine's rounding: the n4sid model of the P- experiment had
#: one at +3.3e14 on an AVX-512 machine (python-control's zeros() keeps all that are
#: not exactly inf) and was called nonminimum phase.
AT_INFINITY = 1e8
#: The fastest pole is taken as at least this, s^-1 (a time constant of 10^4 s): a
#: model of integrators, its poles at 0 or rounding's 1e-8, keeps its zeros up to
#: 1e4 s^-1, far beyond any sampling rate a rig runs at.
SLOWEST_RATE = 1e-4
#: Nor is any bound above this, s^-1.
ZERO_LIMIT = 1e12


def zero_limit(fastest: float) -> float:
    """|z| (s^-1) beyond which a zero of a model whose fastest pole is `fastest`
    (s^-1) is one at infinity: AT_INFINITY times it, within [1e4, ZERO_LIMIT]."""
    return min(AT_INFINITY * max(fastest, SLOWEST_RATE), ZERO_LIMIT)


def finite_zeros(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Finite transmission zeros of the square system (A, B, C, D), sorted by real
    part: the finite generalized eigenvalues (alpha/beta) of the Rosenbrock pencil
    ([[A, B], [C, D]], [[I, 0], [0, 0]]), less those beyond zero_limit of the
    fastest pole; a zero within 1e-12 (relative) of the real axis is made real."""
    from scipy.linalg import eig, eigvals

    n = A.shape[0]
    M = np.block([[A, B], [C, D]])
    N = np.zeros_like(M)
    N[:n, :n] = np.eye(n)
    alpha, beta = eig(M, N, right=False, homogeneous_eigvals=True)
    fastest = float(np.abs(eigvals(A)).max(initial=0.0)) if n else 0.0
    finite = np.abs(alpha) < zero_limit(fastest) * np.abs(beta)
    z = alpha[finite] / beta[finite]
    z = np.where(np.abs(z.imag) < 1e-12 * np.maximum(1.0, np.abs(z.real)), z.real + 0j, z)
    return np.array(sorted(z, key=lambda c: (c.real, c.imag)))


def zoh(A: np.ndarray, B: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretization of x' = A x + B u over a step T:
    Phi = e^(AT), Gamma = int_0^T e^(At) dt B, from one matrix exponential."""
    from scipy.linalg import expm

    n, m = A.shape[0], B.shape[1]
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A * T, B * T
    E = expm(M)
    return E[:n, :n], E[:n, n:]
