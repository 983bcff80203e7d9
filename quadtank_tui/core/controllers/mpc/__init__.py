"""Model predictive control on the plant in use: a linear, constrained,
offset-free MPC with a Kalman filter, solved each sample by OSQP.

- settings.py: what the user chooses (horizons, weights, limits, preview, ...)
- model.py: the linearized, ZOH-discretized model with its disturbance model
- kalman.py: the steady-state Kalman filter on the augmented state
- qp.py: the sparse QP, its OSQP solver and the unconstrained (LQR) gain
- predictive.py: the design and the controller stepped once per sample
- simulate.py: the nonlinear closed loop under MPC or the PI matrix, and its figures
"""
