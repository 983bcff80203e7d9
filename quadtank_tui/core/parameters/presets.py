"""The built-in settings: the preset (P- with the thesis's PI controllers), the
named settings shipped in params/ and those of the other rigs (core.plants)."""

from __future__ import annotations

import dataclasses
from typing import Sequence

from quadtank_tui.core.controllers.general import GeneralParams
from quadtank_tui.core.controllers.mpc.settings import MPCSettings
from quadtank_tui.core.parameters.constants import ControlMode
from quadtank_tui.core.parameters.settings import (
    ControllerElement,
    ControlSettings,
    Parameters,
    SimulationSettings,
)
from quadtank_tui.core.controllers.pid import PIDParams
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.core.plants.johansson import P_MINUS, P_PLUS, Setting
from quadtank_tui.core.plants import Plant
from quadtank_tui.core.plants.spec import PlantSpec
from quadtank_tui.core.controllers.signals import Wave, WaveParams
from quadtank_tui.core.controllers.statefb.settings import StateFeedbackParams


def _pi_element(k: float, ti: float) -> ControllerElement:
    """A PI element, and the same PI as a first-order General controller
    (K + K/(Ti s) = (K s + K/Ti) / s), so both families start out equivalent."""
    return ControllerElement(
        pid=PIDParams(K=k, Ti=ti, Td=0.0, integral=True, derivative=False),
        general=GeneralParams(degree=1, s=(k, k / ti, 0.0, 0.0, 0.0), r=(0.0, 0.0, 0.0, 0.0)),
    )


#: An off-diagonal element that contributes nothing until it is set.
_ZERO_ELEMENT = ControllerElement(
    pid=PIDParams(K=0.0, Ti=30.0, integral=True, derivative=False),
    general=GeneralParams(degree=0, s=(0.0, 0.0, 0.0, 0.0, 0.0), r=(0.0, 0.0, 0.0, 0.0)),
)


def from_setting(setting: Setting, pi1: tuple[float, float], pi2: tuple[float, float],
                 *, tsamp_ms: float = 100.0, settling_time: float = 60.0) -> Parameters:
    """Parameters for a physical setting with decentralized PI controllers
    (K, Ti) on the diagonal; the generators' means are the setting's pump voltages
    (normalized), so Manual mode starts at the operating point.  The state feedback
    linearizes at the setting's lower levels with a settling time in s."""
    means = [round(v / FULL_SCALE_V, 6) for v in setting.op.u]
    refs = tuple(
        WaveParams(wave=Wave.SQUARE, mean=m, amplitude=0.05, period=60.0, on=False, seed=1) for m in means
    )
    return Parameters(
        tsamp_ms=tsamp_ms,
        references=refs,  # type: ignore[arg-type]  # one per pump (two); Parameters checks the count
        control=ControlSettings(),
        controllers=(_pi_element(*pi1), _ZERO_ELEMENT, _ZERO_ELEMENT, _pi_element(*pi2)),
        simulation=SimulationSettings.from_setting(setting),
        statefb=StateFeedbackParams(settling_time=settling_time, level1=setting.op.x[0], level2=setting.op.x[1]),
    )


#: The built-in values ("preset"): P-, PI (3.0, 30) and (2.7, 40), 100 ms.
PRESET: Parameters = from_setting(P_MINUS, (3.0, 30.0), (2.7, 40.0))

#: The named settings shipped in params/ (besides default.par, which equals PRESET).
NAMED_SETTINGS: dict[str, Parameters] = {
    "minphase": PRESET,
    # A nonminimum-phase setting needs settling times an order of magnitude longer
    # (Desautel, chapter 5), and its MPC a look-ahead past the minute-long inverse
    # response: 60 prediction steps of 2 s (120 s) at the loop's 0.1 s.
    "nonminphase": dataclasses.replace(
        from_setting(P_PLUS, (1.5, 110.0), (-0.12, 220.0), settling_time=300.0),
        mpc=MPCSettings(horizon=60, step=2.0)),
}


# --- the other rigs (core.plants) -----------------------------------------------

def from_plant(plant: Plant, levels: Sequence[float], means: Sequence[float], *,
               mode: ControlMode = ControlMode.MANUAL,
               pi1: tuple[float, float] | None = None, pi2: tuple[float, float] | None = None,
               tsamp_ms: float = 100.0) -> Parameters:
    """Parameters for another plant (a PLANT section) operated at `levels`.

    means : the generators' means, normalized (pump voltages in Manual, sensor
        references in Automatic); pi1, pi2 : decentralized PI (K, Ti) on the diagonal,
        zero elements where None (the source gives no PI for that rig)
    """
    refs = tuple(
        WaveParams(wave=Wave.SQUARE, mean=round(m, 6), amplitude=0.05, period=60.0, on=False, seed=1)
        for m in means
    )
    return dataclasses.replace(
        PRESET,
        tsamp_ms=tsamp_ms,
        references=refs,  # type: ignore[arg-type]  # one per mean; Parameters checks there are two
        control=ControlSettings(mode=mode),
        controllers=(_ZERO_ELEMENT if pi1 is None else _pi_element(*pi1), _ZERO_ELEMENT, _ZERO_ELEMENT,
                     _ZERO_ELEMENT if pi2 is None else _pi_element(*pi2)),
        process=PlantSpec.of(plant, levels),
    )


def _plant_settings() -> dict[str, Parameters]:
    from quadtank_tui.core.plants import CoupledCascade, CoupledTITO, DesautelQTP

    ctp = CoupledCascade()
    op = ctp.steady_inputs((15.0, None))  # Desautel 2.1.3: x1 = 15 cm, u_e = 6.77 V
    qtp = DesautelQTP()
    tito = CoupledTITO()
    h0 = (0.115, 0.071)  # Murray-Smith's design point; his PI k1 = 5 (1 + 6.2 s)/s, k2 = 0.56 (1 + 10 s)/s
    return {
        "coupled-cascade": from_plant(ctp, op.x, (op.u[0] / ctp.inputs[0].full_scale, 0.0)),
        "desautel-qtp": from_plant(qtp, qtp.steady_state((6.0, 6.0)), (6.0 / qtp.vmax, 6.0 / qtp.vmax)),
        "coupled-tito": from_plant(tito, h0, [y / FULL_SCALE_V for y in tito.output(h0)],
                                   mode=ControlMode.AUTOMATIC, pi1=(31.0, 6.2), pi2=(5.6, 10.0)),  # K = 5 x 6.2, 0.56 x 10
    }


#: The shipped settings of the other rigs (params/coupled-cascade.par, ...).
PLANT_SETTINGS: dict[str, Parameters] = _plant_settings()
