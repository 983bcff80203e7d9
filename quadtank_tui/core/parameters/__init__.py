"""All of the interface's parameters in one typed, frozen, validated model.

The engine and the UI read their settings from :class:`Parameters`; a `.par` file
is its serialization (``quadtank_tui.files.par``).  Every parameter has a name
``"SECTION.Key"`` exactly as in the `.par` file ("SAMPLING TIME.TSamp",
"REFERENCE ONE.Mean", "CONTROLLER ONE.K", "SIMULATION.Valve1", ...).  Those names
are the public handle: :meth:`Parameters.get`, :meth:`Parameters.with_value`,
:meth:`Parameters.modified_keys`, the scripted experiments and the file reader all
use them, so a parameter cannot be known to one and missing from another.

Ranges live here and only here (the reference and controller ranges in
``WaveParams``/``PIDParams``/``GeneralParams``, which this model composes); a
refused value raises :class:`ParameterError` whose ``field`` is the full key.

The built-in values, :data:`PRESET`, are the paper's minimum-phase setting P- with
the thesis's decentralized PI controllers (3.0, 30) and (2.7, 40) and a sampling
time of 100 ms.  Derived values (diameters from the areas, normalized operating
points, time constants) are rounded to the six decimals of the file format, so the
shipped `.par` files look like the original's and hold the values exactly.

The package, one concern a module: ``constants`` (limits, section names),
``checks`` (validation helpers), ``keys`` (the key table and coercion), ``tree``
(rebuilding the model from plain values), ``settings`` (the dataclasses) and
``presets`` (the built-in settings).  Import from the package itself.  The names
of files and screens (log columns, plot types, file names) are checked by
``quadtank_tui.files.names``, not here.

Example
-------
>>> p = PRESET.with_value("CONTROLLER ONE.K", 2.5)
>>> p.get("CONTROLLER ONE.K"), sorted(p.modified_keys(PRESET))
(2.5, ['CONTROLLER ONE.K'])
"""

from __future__ import annotations

from quadtank_tui.core.controllers.matrix import Family, Structure
from quadtank_tui.core.parameters.constants import (
    CONTROLLER_SECTIONS,
    MAX_ABS,
    OP_POINT_MIN,
    POINTS_MAX,
    POINTS_MAX_ORIGINAL,
    REFERENCE_SECTIONS,
    MPC_SECTION,
    STATEFB_SECTION,
    TSAMP,
    TSAMP_MAX_MS,
    TSAMP_MIN_MS,
    ControlMode,
)
from quadtank_tui.core.parameters.keys import KEYS, SECTIONS, Kind, KeySpec, iter_keys, keys_of, spec
from quadtank_tui.core.parameters.presets import (
    NAMED_SETTINGS,
    PLANT_SETTINGS,
    PRESET,
    from_plant,
    from_setting,
)
from quadtank_tui.core.parameters.settings import (
    ControllerElement,
    ControlSettings,
    LoggingSettings,
    Parameters,
    PlotSettings,
    SimulationSettings,
)

__all__ = [
    "CONTROLLER_SECTIONS", "KEYS", "MAX_ABS", "NAMED_SETTINGS", "OP_POINT_MIN",
    "PLANT_SETTINGS", "POINTS_MAX", "POINTS_MAX_ORIGINAL", "PRESET", "REFERENCE_SECTIONS",
    "MPC_SECTION", "SECTIONS", "STATEFB_SECTION", "TSAMP", "TSAMP_MAX_MS", "TSAMP_MIN_MS",
    "ControlMode", "ControlSettings", "ControllerElement", "Family", "Kind", "KeySpec", "LoggingSettings",
    "Parameters", "PlotSettings", "SimulationSettings", "Structure",
    "from_plant", "from_setting", "iter_keys", "keys_of", "spec",
]
