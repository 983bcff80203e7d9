"""The 2x2 controller matrix (Nunes 1998, 5.3 and 5.5).

Element ij maps error j to input i::

    u_i = sum_j C_ij(r_j, y_j)          full matrix
    u_i = C_ii(r_i, y_i)                decentralized (only C11 and C22)

then the pump inputs saturate to [0, 1] (normalized, 0-10 V).  Every element keeps
both its PID and its General settings (the `.par` file stores both), so the family can
be switched back and forth without losing a tuning.

Switching between decentralized and full matrix within one family keeps the internal
states; switching family resets them (5.3).  Anti-windup acts on the diagonal elements
only: element ii is told the applied input as ``v_ii + (u_i - v_i)``, i.e. the whole
saturation excess of input i, because it is the element that owns input i.

Example
-------
>>> m = ControllerMatrix(1.0)
>>> v = m.compute((0.6, 0.6), (0.5, 0.6))
>>> m.update((0.6, 0.6), (0.5, 0.6), saturate(v))
"""

from __future__ import annotations

from enum import Enum
from typing import Mapping, Sequence

from quadtank_tui.core.controllers.general import General, GeneralParams, realization
from quadtank_tui.core.controllers.pid import PID, PIDParams
from quadtank_tui.core.ranges import ParameterError, check_sampling_time

Element = tuple[int, int]
Pair = tuple[float, float]

#: Matrix elements in `.par` order (CONTROLLER ONE .. FOUR).
ELEMENTS: tuple[Element, ...] = ((1, 1), (1, 2), (2, 1), (2, 2))
DIAGONAL: tuple[Element, ...] = ((1, 1), (2, 2))

#: Actuator range, normalized (0-10 V).
U_MIN, U_MAX = 0.0, 1.0


class Family(str, Enum):
    """Controller family, spelled as the `.par` file's CONTROL `Type`.

    State feedback and MPC are controller types but not matrices of SISO elements:
    the loop runs them from core.controllers.statefb and core.controllers.mpc, and the matrix keeps its own
    family meanwhile."""

    PID = "PID"
    GENERAL = "General"
    STATE_FEEDBACK = "State feedback"
    MPC = "MPC"

    @property
    def whole(self) -> bool:
        """The type owns the 2x2 as a whole (not a matrix of elements)."""
        return self in (Family.STATE_FEEDBACK, Family.MPC)


class Structure(str, Enum):
    """Matrix structure, spelled as the `.par` file's CONTROL `Structure`."""

    DECENTRALIZED = "Decentralized"
    FULL_MATRIX = "FullMatrix"


# An enum member is looked up through a descriptor in Python 3.11 (60 ns): the
# every-sample methods compare with these names instead.
_PID, _FULL_MATRIX = Family.PID, Structure.FULL_MATRIX


def saturate(u: Sequence[float]) -> Pair:
    """Clip both pump inputs to [U_MIN, U_MAX] (normalized): min(U_MAX, max(U_MIN, u))
    written out, as those builtins decide (the first argument unless the second is
    beyond it: a nan gives U_MIN), without their four calls every sample."""
    u1, u2 = float(u[0]), float(u[1])
    u1 = u1 if u1 > U_MIN else U_MIN
    u2 = u2 if u2 > U_MIN else U_MIN
    return (u1 if u1 < U_MAX else U_MAX, u2 if u2 < U_MAX else U_MAX)


def _matrix_family(family: Family | str) -> Family:
    family = Family(family)
    if family.whole:
        raise ParameterError("Type", f"{family.value} is not a matrix family (core.controllers.statefb, core.controllers.mpc run it)")
    return family


def _row_sums(v: Mapping[Element, float]) -> Pair:
    """u_i = sum over j of v_ij: in one pass, in the order and from the start (the
    int 0) that sum() took, so the same bits (0 + -0.0 is 0.0) at half the cost."""
    u1: float = 0
    u2: float = 0
    for (i, _), x in v.items():
        if i == 1:
            u1 += x
        else:
            u2 += x
    return (u1, u2)


def _check_element(i: int, j: int) -> Element:
    if (i, j) not in ELEMENTS:
        raise ParameterError("Element", f"must be one of 11, 12, 21, 22, got {i}{j}")
    return (i, j)


class ControllerMatrix:
    """Four SISO elements of one family in one structure, stepped in two phases.

    Per sample: ``v = compute(r, y)``; the engine applies ``u = saturate(v)``; then
    ``update(r, y, u)`` in Automatic or ``track(r, y, u)`` in Manual.  ``r`` and ``y``
    are (channel 1, channel 2) pairs, normalized.
    """

    def __init__(
        self,
        h: float,
        family: Family = Family.PID,
        structure: Structure = Structure.DECENTRALIZED,
        *,
        pid: Mapping[Element, PIDParams] | None = None,
        general: Mapping[Element, GeneralParams] | None = None,
    ) -> None:
        h = check_sampling_time(h)
        self._family = _matrix_family(family)
        self._structure = Structure(structure)
        pid = pid or {}
        general = general or {}
        self._pid = {
            e: PID(pid.get(e, PIDParams()), h, anti_windup=e in DIAGONAL) for e in ELEMENTS
        }
        self._general = {e: General(general.get(e, GeneralParams()), h) for e in ELEMENTS}
        # This sample's compute: (r, y, v_ij, their row sums), which update reuses when
        # it is handed the same r and y objects (the engine's sample: compute, write,
        # update); any other change of the elements forgets it.
        self._computed: tuple[Sequence[float], Sequence[float], dict[Element, float], Pair] | None = None

    # --- what is configured ------------------------------------------------------------

    @property
    def family(self) -> Family:
        return self._family

    @property
    def structure(self) -> Structure:
        return self._structure

    @property
    def h(self) -> float:
        """Sampling time, s."""
        return self._pid[(1, 1)].h

    def pid_params(self, i: int, j: int) -> PIDParams:
        return self._pid[_check_element(i, j)].params

    def general_params(self, i: int, j: int) -> GeneralParams:
        return self._general[_check_element(i, j)].params

    def active_elements(self) -> tuple[Element, ...]:
        """The elements that contribute to u in the current structure."""
        return ELEMENTS if self._structure is _FULL_MATRIX else DIAGONAL

    # --- one sample ------------------------------------------------------------------------

    def element_outputs(self, r: Sequence[float], y: Sequence[float]) -> dict[Element, float]:
        """v_ij of every active element for this sample (pure), normalized."""
        out: dict[Element, float] = {}
        if self._family is _PID:
            pid = self._pid
            for e in self.active_elements():
                j = e[1] - 1
                out[e] = pid[e].compute(r[j], y[j])
        else:
            general = self._general
            for e in self.active_elements():
                j = e[1] - 1
                out[e] = general[e].compute(r[j] - y[j])
        return out

    def compute(self, r: Sequence[float], y: Sequence[float]) -> Pair:
        """Unsaturated inputs (u1, u2) for this sample; no state change.  An update
        with the same r and y objects reuses it: a caller that changes them in place
        in between (a list, an array) must hand update copies."""
        v = self.element_outputs(r, y)
        total = _row_sums(v)
        self._computed = (r, y, v, total)
        return total

    def update(self, r: Sequence[float], y: Sequence[float], u_applied: Sequence[float]) -> None:
        """Automatic: commit the sample after ``u_applied`` (saturated) went out."""
        computed, self._computed = self._computed, None
        if computed is not None and computed[0] is r and computed[1] is y:
            v, total = computed[2], computed[3]  # what compute() gave for these r and y: the same numbers
        else:
            v = self.element_outputs(r, y)
            total = _row_sums(v)
        pid = self._family is _PID
        for (i, j), vij in v.items():
            rj, yj = r[j - 1], y[j - 1]
            if pid:
                # The diagonal element sees the whole saturation excess of its input.
                applied = vij + (u_applied[i - 1] - total[i - 1]) if i == j else vij
                self._pid[(i, j)].update(rj, yj, applied, vij)
            else:
                self._general[(i, j)].update(rj - yj)

    def track(self, r: Sequence[float], y: Sequence[float], u_applied: Sequence[float]) -> None:
        """Manual: follow the applied inputs so that Automatic starts from them.

        The diagonal element i carries all of u_i; active off-diagonal elements are
        held at rest at zero output, so nothing winds up in them while the loop is open.
        """
        self._computed = None
        elements = self._pid if self._family is _PID else None
        for e in self.active_elements():
            i, j = e
            rj, yj = r[j - 1], y[j - 1]
            target = float(u_applied[i - 1]) if i == j else 0.0
            if elements is not None:
                elements[e].track(rj, yj, target)
            else:
                self._general[e].track(rj - yj, target)

    # --- changes ----------------------------------------------------------------------------

    def set_element_params(self, i: int, j: int, params: PIDParams | GeneralParams) -> None:
        """New PID or General settings for element ij (bumpless if it is running)."""
        e = _check_element(i, j)
        self._computed = None
        if isinstance(params, PIDParams):
            self._pid[e].set_params(params)
        elif isinstance(params, GeneralParams):
            self._general[e].set_params(params)
        else:
            raise TypeError(f"expected PIDParams or GeneralParams, got {type(params).__name__}")

    def set_type(self, family: Family, structure: Structure) -> None:
        """Choose family and structure (5.3): a new family starts from reset states;
        within a family the states are kept, and off-diagonal elements switched in by
        going to full matrix start from rest (they had no part in the decentralized
        controller)."""
        family, structure = _matrix_family(family), Structure(structure)
        self._computed = None
        if family is not self._family:
            self._family = family
            self._structure = structure
            self.reset()
            return
        if structure is Structure.FULL_MATRIX and self._structure is Structure.DECENTRALIZED:
            for e in ELEMENTS:
                if e not in DIAGONAL:
                    self.reset_element(*e)
        self._structure = structure

    def reset(self) -> None:
        """Reset the internal states of all four elements (the Controller Reset button)."""
        for e in ELEMENTS:
            self.reset_element(*e)

    def reset_element(self, i: int, j: int) -> None:
        """Reset one element's states (its own Reset button), both families."""
        e = _check_element(i, j)
        self._computed = None
        self._pid[e].reset()
        self._general[e].reset()

    def set_sampling_time(self, h: float) -> None:
        """New sampling time, s, for every element; all or nothing.

        Every General element is re-discretized first as a check, so a pole that Tustin
        cannot map at the new h refuses the change before any element has moved.
        """
        h = check_sampling_time(h)
        self._computed = None
        for g in self._general.values():
            realization(g.params.numerator, g.params.denominator, h)
        for e in ELEMENTS:
            self._pid[e].set_sampling_time(h)
            self._general[e].set_sampling_time(h)


__all__ = [
    "DIAGONAL", "ELEMENTS", "U_MAX", "U_MIN", "ControllerMatrix", "Element", "Family",
    "Structure", "saturate",
]
