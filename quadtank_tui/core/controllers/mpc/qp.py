"""The MPC's quadratic program in its sparse form, solved by OSQP with warm start.

Sparse, not condensed: the variables are the predicted states x_0..x_N, the inputs
u_0..u_{N-1} and one slack per level, tied by the model as equality rows.  Every
block is banded, so the number of nonzeros grows with N (the condensed form's
Hessian and state-limit rows are dense, growing with N^2 and needing powers of A),
OSQP factors the KKT matrix once at setup, and each sample changes only vectors:
the measured state, the disturbance estimate, the targets and the last input enter
the bounds and the linear cost.

Cost (deviations from the operating point, targets x_s,k u_s,k from the reference
and the disturbance estimate)::

    sum_{k<N} |x_k - x_s,k|_Q^2 + |u_k - u_s,k|_R^2 + |u_k - u_{k-1}|_S^2
      + |[x_N; u_{N-1}] - [x_s,N; u_s,N]|_P^2 + w (|s|^2 + sum s)

P is the infinite-horizon cost of the LQR on [x; u_prev] (the rate weight makes the
last input part of the state), so without active limits the first move is exactly
the LQR's at any horizon (the test compares to scipy's solve_discrete_are).
Constraints: pumps within their range (hard), optional rate limits (hard), levels
within [floor, brim - margin] widened by the slack s >= 0 (soft, so the problem is
always feasible), inputs held after the control horizon.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.linalg import solve_discrete_are

from quadtank_tui.core.controllers.mpc.model import MPCModel
from quadtank_tui.core.controllers.mpc.settings import MPCSettings

#: OSQP settings.  ADMM alone is a poor judge of u_0 here: at a short sampling time
#: one sample's input moves the cost very little, so a dual tolerance that ADMM
#: reaches in a few hundred iterations leaves u_0 off by tenths of a volt (measured:
#: 0.27 V at T = 0.1 s, N = 30 with 1e-4).  Polishing solves the KKT system of the
#: active set ADMM found, exactly (u_0 within 1e-6 V of the LQR's), so ADMM only needs
#: to find the active set: loose tolerances, and the solve stays within milliseconds.
OSQP_SETTINGS = dict(eps_abs=1e-3, eps_rel=1e-3, max_iter=4000, polishing=True, warm_starting=True,
                     verbose=False)


@dataclass(frozen=True, eq=False)
class Weights:
    """Q (n x n, on the tracked levels), R and S (m x m), the terminal P ((n+m)^2),
    and the LQR gain K (m x (n+m), u = -K [x; u_prev]) P comes with."""

    Q: np.ndarray
    R: np.ndarray
    S: np.ndarray
    P: np.ndarray
    K: np.ndarray


def weights(model: MPCModel, s: MPCSettings) -> Weights:
    """The weights in plant units and the LQR on [x; u_prev] they define."""
    n, m = model.n, model.m
    qz = s.output_weight / model.y_scale[list(model.tracked)] ** 2
    Q = model.Cz.T @ np.diag(qz) @ model.Cz
    R = np.diag(s.input_weight / model.u_scale ** 2)
    S = np.diag(s.rate_weight / model.u_scale ** 2)
    Aa = np.block([[model.A, np.zeros((n, m))], [np.zeros((m, n + m))]])
    Ba = np.vstack([model.B, np.eye(m)])
    Qa = np.block([[Q, np.zeros((n, m))], [np.zeros((m, n)), S]])
    Na = np.vstack([np.zeros((n, m)), -S])
    P = solve_discrete_are(Aa, Ba, Qa, R + S, s=Na)
    K = np.linalg.solve(R + S + Ba.T @ P @ Ba, Ba.T @ P @ Aa + Na.T)
    return Weights(Q, R, S, P, K)


class SparseQP:
    """The QP of one sample; :meth:`solve` updates the vectors and calls OSQP."""

    def __init__(self, model: MPCModel, s: MPCSettings, w: Weights | None = None, *,
                 first_dt: float | None = None) -> None:
        """`model` at the prediction step; `first_dt`: seconds before the first move
        is replaced (the loop's sampling time when the QP is solved every sample on a
        coarser grid: the rate limit allows that much change from the last input)."""
        import osqp  # loaded with the controller, not with the package

        self.model, self.settings = model, s
        self._first_dt = model.T if first_dt is None else first_dt
        self.w = w or weights(model, s)
        n, m, N = model.n, model.m, s.horizon
        self.N = N
        self.nx, self.nu = (N + 1) * n, N * m
        self.nv = self.nx + self.nu + n
        self._H = self._hessian()
        A, lo, hi, eq_rows = self._constraints()
        self._A, self._lo, self._hi, self._eq_rows = A, lo, hi, eq_rows
        # the variables OSQP sees are relative to the ranges (levels / tank height, volts
        # / pump range): every block then has entries of order one
        self._D = np.concatenate([np.tile(model.y_scale, N + 1), np.tile(model.u_scale, N), model.y_scale])
        Dm = sp.diags(self._D)
        self._solver = osqp.OSQP()
        self._solver.setup(sp.triu(Dm @ (2.0 * self._H) @ Dm, format="csc"), np.zeros(self.nv),
                           (A @ Dm).tocsc(), lo, hi, **OSQP_SETTINGS)
        self._status_ok = {osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE}
        self._kkt: tuple[tuple[np.ndarray, np.ndarray], np.ndarray] | None = None

    # --- indices ------------------------------------------------------------------------

    def xi(self, k: int) -> slice:
        n = self.model.n
        return slice(k * n, (k + 1) * n)

    def ui(self, k: int) -> slice:
        m = self.model.m
        return slice(self.nx + k * m, self.nx + (k + 1) * m)

    @property
    def si(self) -> slice:
        return slice(self.nx + self.nu, self.nv)

    # --- the fixed matrices ----------------------------------------------------------------

    def _hessian(self) -> sp.csc_matrix:
        """H with cost v' H v + c' v (OSQP's P is 2 H)."""
        mdl, w, N, n = self.model, self.w, self.N, self.model.n
        H = sp.lil_matrix((self.nv, self.nv))
        for k in range(1, N):
            H[self.xi(k), self.xi(k)] = w.Q
        for k in range(N):
            H[self.ui(k), self.ui(k)] = w.R + w.S + (w.S if k < N - 1 else 0)
            if k:
                H[self.ui(k), self.ui(k - 1)] = -w.S
                H[self.ui(k - 1), self.ui(k)] = -w.S
        H[self.xi(N), self.xi(N)] = w.P[:n, :n]
        H[self.xi(N), self.ui(N - 1)] = w.P[:n, n:]
        H[self.ui(N - 1), self.xi(N)] = w.P[n:, :n]
        H[self.ui(N - 1), self.ui(N - 1)] = H[self.ui(N - 1), self.ui(N - 1)].toarray() + w.P[n:, n:]
        H[self.si, self.si] = np.diag(self.settings.slack_weight / mdl.y_scale ** 2)
        return H.tocsc()

    def _constraints(self) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray, dict[str, slice]]:
        mdl, s, N = self.model, self.settings, self.N
        n, m = mdl.n, mdl.m
        blocks: list[sp.spmatrix] = []
        lo: list[np.ndarray] = []
        hi: list[np.ndarray] = []
        rows: dict[str, slice] = {}

        def add(name: str, M: sp.spmatrix, l: np.ndarray, u: np.ndarray) -> None:
            start = sum(b.shape[0] for b in blocks)
            blocks.append(M)
            lo.append(l)
            hi.append(u)
            rows[name] = slice(start, start + M.shape[0])

        def sel(sl: slice) -> sp.csr_matrix:
            return sp.eye(self.nv, format="csr")[sl]

        add("x0", sel(self.xi(0)), np.zeros(n), np.zeros(n))
        dyn = sp.lil_matrix((N * n, self.nv))
        for k in range(N):
            r = slice(k * n, (k + 1) * n)
            dyn[r, self.xi(k + 1)] = np.eye(n)
            dyn[r, self.xi(k)] = -mdl.A
            dyn[r, self.ui(k)] = -mdl.B
        add("dyn", dyn.tocsr(), np.zeros(N * n), np.zeros(N * n))
        add("u", sel(slice(self.nx, self.nx + self.nu)), np.tile(mdl.u_lo - mdl.u_e, N), np.tile(mdl.u_hi - mdl.u_e, N))
        held = N - s.moves
        if held:
            hold = sp.lil_matrix((held * m, self.nv))
            for j, k in enumerate(range(s.moves, N)):
                hold[j * m:(j + 1) * m, self.ui(k)] = np.eye(m)
                hold[j * m:(j + 1) * m, self.ui(s.moves - 1)] = -np.eye(m)
            add("hold", hold.tocsr(), np.zeros(held * m), np.zeros(held * m))
        if s.rate_limit > 0:
            du = np.full(N * m, s.rate_limit * mdl.T)
            du[:m] = s.rate_limit * self._first_dt
            rate = sp.lil_matrix((N * m, self.nv))
            for k in range(N):
                rate[k * m:(k + 1) * m, self.ui(k)] = np.eye(m)
                if k:
                    rate[k * m:(k + 1) * m, self.ui(k - 1)] = -np.eye(m)
            add("rate", rate.tocsr(), -du, du)
        lev_lo = sp.lil_matrix((N * n, self.nv))
        lev_hi = sp.lil_matrix((N * n, self.nv))
        for k in range(1, N + 1):
            r = slice((k - 1) * n, k * n)
            for M, sign in ((lev_lo, 1.0), (lev_hi, -1.0)):
                M[r, self.xi(k)] = np.eye(n)
                M[r, self.si] = sign * np.eye(n)
        inf = np.full(N * n, np.inf)
        add("lev_lo", lev_lo.tocsr(), np.tile(mdl.x_lo - mdl.x_e, N), inf)
        add("lev_hi", lev_hi.tocsr(), -inf, np.tile(mdl.x_hi - mdl.x_e, N))
        add("slack", sel(self.si), np.zeros(n), np.full(n, np.inf))
        return sp.vstack(blocks, format="csc"), np.concatenate(lo), np.concatenate(hi), rows

    # --- one sample ------------------------------------------------------------------------

    def vectors(self, x0: np.ndarray, d: np.ndarray, xs: np.ndarray, us: np.ndarray,
                u_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, l, u) for the state x0, disturbance d, targets xs (N+1, n), us (N+1, m)
        and the input applied last (all deviations)."""
        mdl, w, N, n = self.model, self.w, self.N, self.model.n
        q = np.zeros(self.nv)
        q[n: N * n] = (-2.0 * xs[1:N] @ w.Q.T).ravel()  # x_1 .. x_{N-1}
        q[self.nx: self.nx + self.nu] = (-2.0 * us[:N] @ w.R.T).ravel()
        q[self.ui(0)] += -2.0 * w.S @ u_prev
        tN = -2.0 * w.P @ np.concatenate([xs[N], us[N]])
        q[self.xi(N)] += tN[:n]
        q[self.ui(N - 1)] += tN[n:]
        q[self.si] = self.settings.slack_weight / mdl.y_scale
        lo, hi = self._lo.copy(), self._hi.copy()
        rows = self._eq_rows
        lo[rows["x0"]] = hi[rows["x0"]] = x0
        lo[rows["dyn"]] = hi[rows["dyn"]] = np.tile(mdl.Bd @ d, N)
        if "rate" in rows:
            first = slice(rows["rate"].start, rows["rate"].start + mdl.m)
            lo[first] += u_prev
            hi[first] += u_prev
        return q, lo, hi

    def solve(self, q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray | None, str]:
        """The optimal variables, or None and OSQP's status when it did not solve."""
        self._solver.update(q=self._D * q, l=lo, u=hi)
        res = self._solver.solve(raise_error=False)
        if res.info.status_val not in self._status_ok or res.x is None or not np.all(np.isfinite(res.x)):
            return None, str(res.info.status)
        return self._D * np.asarray(res.x), str(res.info.status)

    def unconstrained_move(self, q: np.ndarray, lo: np.ndarray) -> np.ndarray:
        """u_0 of the sample's QP (vectors q, lo) with no inequality active: the KKT
        system of its equalities (the model, the held moves), factored once.  Affine in
        the state, disturbance, targets and last input: a bumpless start solves for the
        estimate that makes it the input in force."""
        if self._kkt is None:
            from scipy.linalg import lu_factor

            keep = np.arange(self.nx + self.nu)
            eq = [self._eq_rows[k] for k in ("x0", "dyn", "hold") if k in self._eq_rows]
            E = sp.vstack([self._A[r] for r in eq]).toarray()[:, keep]
            H = self._H.toarray()[np.ix_(keep, keep)]
            ne = E.shape[0]
            self._kkt = (lu_factor(np.block([[2.0 * H, E.T], [E, np.zeros((ne, ne))]])),
                         np.concatenate([np.arange(r.start, r.stop) for r in eq]))
        from scipy.linalg import lu_solve

        lu, rows = self._kkt
        sol = lu_solve(lu, np.concatenate([-q[: self.nx + self.nu], lo[rows]]))
        return sol[self.ui(0)]

    def unconstrained_gain(self) -> np.ndarray:
        """K (m x (n+m)) with u_0 = -K [x_0; u_prev] when no inequality is active:
        the KKT system of the equality-constrained QP, solved for each column."""
        n, m = self.model.n, self.model.m
        keep = np.arange(self.nx + self.nu)  # the slacks are 0 without active level limits
        eq = [self._eq_rows[k] for k in ("x0", "dyn", "hold") if k in self._eq_rows]
        E = sp.vstack([self._A[r] for r in eq]).toarray()[:, keep]
        H = self._H.toarray()[np.ix_(keep, keep)]
        ne = E.shape[0]
        KKT = np.block([[2.0 * H, E.T], [E, np.zeros((ne, ne))]])
        rhs = np.zeros((len(keep) + ne, n + m))
        rhs[len(keep):len(keep) + n, :n] = np.eye(n)  # x_0 = x (the first equality rows)
        rhs[self.ui(0), n:] = 2.0 * self.w.S  # -c = 2 S u_prev on u_0
        sol = np.linalg.solve(KKT, rhs)
        return -sol[self.ui(0)]
