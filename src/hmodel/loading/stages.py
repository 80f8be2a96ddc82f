"""Stages: the one description of a loading segment by named rows (report §1.1.2).

A stage names what each of its rows controls (:data:`ROWS`: strain changes over the stage,
stress targets reached linearly over its increments) and builds the :class:`Segment` the one
runner (:func:`~hmodel.loading.segment.run_segment`) runs. Loading programs are made of stages;
the named paths of :mod:`hmodel.loading.named_paths` (drained and undrained biaxial, oedometric,
constant p, proportional) are the stages of :data:`PRESETS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..limits import steps_for
from ..rev import RevState
from .expressions import Criterion, Expression
from .segment import Segment

#: Default axial strain increment of biaxial, oedometric and constant-p paths.
AXIAL_STEP = 1e-4

#: Named rows: (a stress row?, coefficients on (11, 22, 12)).
ROWS = {"eps11": (False, (1, 0, 0)), "eps22": (False, (0, 1, 0)), "eps12": (False, (0, 0, 1)),
        "eps_v": (False, (1, 1, 0)), "sig11": (True, (1, 0, 0)), "sig22": (True, (0, 1, 0)),
        "sig12": (True, (0, 0, 1)), "p": (True, (0.5, 0.5, 0)), "q": (True, (1, -1, 0))}
#: Components named by the single-component rows (a component controlled twice is an error).
_COMPONENT = {"eps11": "11", "sig11": "11", "eps22": "22", "sig22": "22", "eps12": "12", "sig12": "12"}
#: Presets: the rows they fix (value, or "hold") and the rows one of which drives them.
PRESETS = {
    "drained": ({"sig22": "hold", "eps12": 0.0}, ("eps11", "q", "sig11")),
    "undrained": ({"eps_v": 0.0, "eps12": 0.0}, ("eps11", "q")),
    "oedometric": ({"eps22": 0.0, "eps12": 0.0}, ("eps11", "sig11")),
    "constant_p": ({"p": "hold", "eps12": 0.0}, ("eps11", "q")),
}
#: Increments of a stage whose strain rows do not move (a stress-controlled stage) by default.
DEFAULT_STEPS = 100


@dataclass(frozen=True)
class Stage:
    """One segment: ``rows`` maps each of three row names (:data:`ROWS`) to a strain change, a
    stress target (:class:`Expression` of ``p0``) or ``"hold"``; or, with ``iso`` set, an
    isotropic consolidation to that pressure [Pa] in strain increments ``max_increment``."""

    name: str
    rows: Mapping[str, object] = field(default_factory=dict)
    steps: int | None = None
    max_increment: float | None = None
    until: Criterion | None = None
    iso: float | None = None
    #: an increment that cannot be solved ends the program (recorded in ``meta["stopped"]``)
    #: instead of failing it: flow under stress control, e.g. cyclic liquefaction
    stop_on_failure: bool = False

    def segment(self, state: RevState, p0=None) -> Segment:
        """The :class:`Segment` of this stage for the points of ``state`` (``p0``: for targets
        using it, one value or one per point). Its rows are in component order
        (:func:`component_order`); a row's value may be one per point (B,)."""
        names = component_order(list(self.rows))
        S = tuple(ROWS[n][0] for n in names)
        M = np.array([ROWS[n][1] for n in names], float)
        values = []
        for n, row in zip(names, M):
            v = self.rows[n]
            if isinstance(v, str) and v == "hold":
                v = state.sig @ row
            elif isinstance(v, Expression):
                v = self.target(n, v, p0)
            values.append(np.asarray(v, float))
        shape = np.broadcast_shapes(*(v.shape for v in values))
        values = np.stack([np.broadcast_to(v, shape) for v in values], axis=-1)
        if values.ndim == 2 and state.n_points == 1 and len(values) == 1:
            values = values[0]
        return Segment(S, M, values, self.n_steps(), self.name)

    def target(self, row: str, expression: Expression, p0) -> float | np.ndarray:
        """The stress target of ``row`` at ``p0`` (one value or one per point): finite
        numbers, or an InputError."""
        if "p0" in expression.names and p0 is None:
            raise InputError(f"stage {self.name!r}: {row} = {expression.text!r} uses p0, but no iso "
                             f"stage comes before it")
        v = np.asarray(expression({"p0": p0}), float)
        if not np.all(np.isfinite(v)):
            raise InputError(f"stage {self.name!r}: {row} = {expression.text!r} is not a finite "
                             f"stress at p0 = {np.asarray(p0, float).tolist()} Pa")
        return float(v) if v.ndim == 0 else v

    def n_steps(self) -> int:
        """``steps``, or the largest strain change over ``max_increment`` (default
        :data:`AXIAL_STEP`); :data:`DEFAULT_STEPS` when no strain row moves."""
        if self.steps is not None:
            return self.steps
        change = max([abs(v) for n, v in self.rows.items() if not ROWS[n][0]] + [0.0])
        if change == 0:
            return DEFAULT_STEPS
        return steps_for(change, self.max_increment or AXIAL_STEP, f"stage {self.name!r}: increments")


def component_order(names: list[str]) -> list[str]:
    """Rows in component order: a row on one component (``eps22``, ``sig22``) in that
    component's place, the combinations (``eps_v``, ``p``, ``q``) in the places left, in the
    order given. Both drivers then see one segment whatever order a program lists its rows in.

    >>> component_order(["sig22", "eps12", "eps11"])
    ['eps11', 'sig22', 'eps12']
    >>> component_order(["eps_v", "eps11", "eps12"])
    ['eps11', 'eps_v', 'eps12']
    """
    order = ("11", "22", "12")
    slots: list[str | None] = [None] * len(names)
    rest = []
    for name in names:
        comp = _COMPONENT.get(name)
        if comp is not None and comp in order and order.index(comp) < len(slots) and slots[order.index(comp)] is None:
            slots[order.index(comp)] = name
        else:
            rest.append(name)
    return [s if s is not None else rest.pop(0) for s in slots]
