"""The steady-state Kalman filter on the model augmented with its disturbances.

The augmented state [x; d] is estimated from the measured levels.  The noise
levels are relative to the ranges (the model's y_scale, u_scale): a measurement
noise of 0.1 % of the tank height per reading, state noise of 0.05 % and
disturbance noise of 1.4 % (of the pump range for an input disturbance, of the
tank height for an output one) per square-root second, so the filter's speed does
not depend on the sampling time: it estimates a leak or a wrong pump constant in
tens of seconds while a single noisy reading moves little (tuned on the P+ leak:
0.5 %/sqrt(s) left a 7 % larger IAE).
The filter form (x_k|k) is used: the controller acts on the level just read.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_discrete_are

from quadtank_tui.core.controllers.mpc.model import MPCModel

MEAS_NOISE = 1e-3
STATE_NOISE = 5e-4
DIST_NOISE = 1.4e-2


def disturbance_scale(model: MPCModel) -> np.ndarray:
    """The range each disturbance is relative to (pump ranges, then tank heights)."""
    m = model.m
    if model.disturbance == "input":
        out_rows = np.nonzero(model.Cd[:, m:])[0] if model.nd > m else np.array([], dtype=int)
        heights = model.y_scale[[model.measured[i] for i in out_rows]]
        return np.concatenate([model.u_scale, heights])
    return model.y_scale[list(model.measured)]


class KalmanFilter:
    """x_hat, d_hat from the measured levels (deviations) and the applied pumps."""

    def __init__(self, model: MPCModel) -> None:
        n, nd = model.n, model.nd
        self.model = model
        self.Aa = np.block([[model.A, model.Bd], [np.zeros((nd, n)), np.eye(nd)]])
        self.Ba = np.vstack([model.B, np.zeros((nd, model.m))])
        self.Ca = np.hstack([model.Cm, model.Cd])
        q = model.T * np.concatenate([(STATE_NOISE * model.y_scale) ** 2, (DIST_NOISE * disturbance_scale(model)) ** 2])
        r = (MEAS_NOISE * model.y_scale[list(model.measured)]) ** 2
        P = solve_discrete_are(self.Aa.T, self.Ca.T, np.diag(q), np.diag(r))
        S = self.Ca @ P @ self.Ca.T + np.diag(r)
        self.L = P @ self.Ca.T @ np.linalg.inv(S)
        self._pred = np.zeros(n + nd)
        self._est = self._pred.copy()

    def reset(self, x: np.ndarray, d: np.ndarray | None = None) -> None:
        """Start at state x (deviations), disturbance d (default zero)."""
        self._pred = np.concatenate([x, np.zeros(self.model.nd) if d is None else d])
        self._est = self._pred.copy()

    @property
    def estimate(self) -> np.ndarray:
        """The last estimate [x; d] (deviations)."""
        return self._est.copy()

    def correct(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The estimate given this sample's measured levels: (x_hat, d_hat)."""
        est = self._pred + self.L @ (y - self.Ca @ self._pred)
        self._est = est
        n = self.model.n
        return est[:n], est[n:]

    def coast(self) -> None:
        """No usable reading this sample: the estimate is the prediction."""
        self._est = self._pred.copy()

    def predict(self, u: np.ndarray) -> None:
        """Advance to the next sample with the pumps u (deviations) applied."""
        self._pred = self.Aa @ self._est + self.Ba @ u
