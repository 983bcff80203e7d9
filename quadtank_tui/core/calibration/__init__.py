"""Level-sensor calibration (Desautel 2.3; B9).

fits.py       the fits: each sensor's gain and offset, the plant's outlets from the pairs
procedure.py  the steady-state procedure as a state machine, fed the reads one at a time
              (the engine runs it in the Calibration window, daq/calibrate.py on a rig)
"""
