"""The controllers, one sample at a time, in the loop's normalized units.

pid.py       PID with the original's filtered derivative, anti-windup and bumpless transfer
general.py   the General controller (a discrete transfer function per loop)
matrix.py    the 2x2 controller matrix: which controller acts from which error to which pump
signals.py   references and waves (square, sine, PRBS) the loop adds to the means
statefb/     state-feedback tracking with its smart integrator (Desautel)
mpc/         model predictive control: the model, Kalman filter, QP, the controller

Import from the modules: the package imports nothing (the parameter model needs
pid.py and statefb/settings.py, and must not load scipy through the rest).
"""
