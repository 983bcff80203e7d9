"""The IST Lisbon quadruple-tank rig (Pedroso and Batista, J. Process Control 118,
2022; github.com/decenter2021/quadruple-tank-setup): its serial protocol
(protocol.py, pure), its DAQ configuration (config.py), the backend that drives it
over a serial port (backend.py) and a virtual device on a pseudo-terminal that
behaves as its Arduino firmware does (device.py)."""
