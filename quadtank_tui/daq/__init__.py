"""DAQ: Active mode through a real data-acquisition link, and the virtual rig.

- `config`: the DAQ configuration file (register map, Table 1 channel map,
  calibration, output limits, interlock) with a LabJack T-series preset;
- `modbus`: the Modbus TCP process backend the engine drives in Active mode;
- `interlock`: the high-level interlock (cut the pump feeding an overfull tank);
- `rig` + `server`: the virtual rig, the simulator served over Modbus TCP;
- `registers`: FLOAT32 / scaled-integer register codec shared by both ends.

This package sits at the engine's level: it implements `engine.backend` and uses
the pure core; the core never imports it.
"""
