"""Stages: the one description of a loading segment by named rows (report §1.1.2).

A stage names what each of its rows controls (:data:`ROWS`: strain changes over the stage,
stress targets reached linearly over its increments) and builds the :class:`Segment` the one
runner (:func:`~hmodel.loading.segment.run_segment`) runs. Loading programs are made of stages;
the named paths of :mod:`hmodel.loading.named_paths` (drained and undrained biaxial, oedometric,
constant p, proportional) are the stages of :data:`PRESETS`.

Stages on 3D states (:class:`~hmodel.rev.rev3d.Rev3D`, six components) name six rows of
:data:`ROWS_3D` and have the presets of :data:`PRESETS_3D` (the triaxial test drained and
undrained, oedometric, constant p, true triaxial at constant p and b); a stage whose rows are
not those of its REV's dimension is refused (:func:`check_row_names`).
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

#: Named rows of 2D stages: (a stress row?, coefficients on (11, 22, 12)).
ROWS = {"eps11": (False, (1, 0, 0)), "eps22": (False, (0, 1, 0)), "eps12": (False, (0, 0, 1)),
        "eps_v": (False, (1, 1, 0)), "sig11": (True, (1, 0, 0)), "sig22": (True, (0, 1, 0)),
        "sig12": (True, (0, 0, 1)), "p": (True, (0.5, 0.5, 0)), "q": (True, (1, -1, 0))}
#: Named rows of 3D stages: (a stress row?, coefficients on (11, 22, 33, 23, 13, 12), tensor
#: shear; axis 1 axial): p = tr σ/3, q = σ11 - (σ22 + σ33)/2, eps_v = tr ε, the differences
#: of the lateral components (axisymmetry), the radial stress sig_r = (σ22 + σ33)/2, and ``b``, whose value b in [0, 1] makes the row
#: (σ22 - σ33) - b (σ11 - σ33) = 0 (:func:`b_row`; principal stresses along 1, 2, 3).
ROWS_3D = {"eps11": (False, (1, 0, 0, 0, 0, 0)), "eps22": (False, (0, 1, 0, 0, 0, 0)),
           "eps33": (False, (0, 0, 1, 0, 0, 0)), "eps23": (False, (0, 0, 0, 1, 0, 0)),
           "eps13": (False, (0, 0, 0, 0, 1, 0)), "eps12": (False, (0, 0, 0, 0, 0, 1)),
           "eps_v": (False, (1, 1, 1, 0, 0, 0)), "eps22-eps33": (False, (0, 1, -1, 0, 0, 0)),
           "sig11": (True, (1, 0, 0, 0, 0, 0)), "sig22": (True, (0, 1, 0, 0, 0, 0)),
           "sig33": (True, (0, 0, 1, 0, 0, 0)), "sig23": (True, (0, 0, 0, 1, 0, 0)),
           "sig13": (True, (0, 0, 0, 0, 1, 0)), "sig12": (True, (0, 0, 0, 0, 0, 1)),
           "p": (True, (1 / 3, 1 / 3, 1 / 3, 0, 0, 0)), "q": (True, (1, -0.5, -0.5, 0, 0, 0)),
           "sig22-sig33": (True, (0, 1, -1, 0, 0, 0)), "sig_r": (True, (0, 0.5, 0.5, 0, 0, 0)),
           "b": (True, None)}
#: Components named by the single-component rows (a component controlled twice is an error).
_COMPONENT = {"eps11": "11", "sig11": "11", "eps22": "22", "sig22": "22", "eps12": "12", "sig12": "12"}
_COMPONENT_3D = {**_COMPONENT, "eps33": "33", "sig33": "33", "eps23": "23", "sig23": "23",
                 "eps13": "13", "sig13": "13"}
#: Components of a state by their number (2D: 3, 3D: 6), in state order.
_ORDER = {3: ("11", "22", "12"), 6: ("11", "22", "33", "23", "13", "12")}
#: Presets: the rows they fix (value, or "hold") and the rows one of which drives them.
PRESETS = {
    "drained": ({"sig22": "hold", "eps12": 0.0}, ("eps11", "q", "sig11")),
    "undrained": ({"eps_v": 0.0, "eps12": 0.0}, ("eps11", "q")),
    "oedometric": ({"eps22": 0.0, "eps12": 0.0}, ("eps11", "sig11")),
    "constant_p": ({"p": "hold", "eps12": 0.0}, ("eps11", "q")),
}
_SHEARS_3D = {"eps23": 0.0, "eps13": 0.0, "eps12": 0.0}
#: Presets of 3D stages (axis 1 axial, the shear strains held): the triaxial test drained
#: (σ22 = σ33 held) or undrained (eps_v = 0, eps22 = eps33), oedometric (eps22 = eps33 = 0),
#: axisymmetric at constant p (σ22 = σ33), and true triaxial (constant p and constant b).
PRESETS_3D = {
    "drained": ({"sig22": "hold", "sig33": "hold", **_SHEARS_3D}, ("eps11", "q", "sig11")),
    "undrained": ({"eps_v": 0.0, "eps22-eps33": 0.0, **_SHEARS_3D}, ("eps11", "q")),
    "oedometric": ({"eps22": 0.0, "eps33": 0.0, **_SHEARS_3D}, ("eps11", "sig11")),
    "constant_p": ({"p": "hold", "sig22-sig33": 0.0, **_SHEARS_3D}, ("eps11", "q")),
    "true_triaxial": ({"p": "hold", "b": 0.0, **_SHEARS_3D}, ("eps11",)),
}
#: Rows, presets and components by the number of components of the REV's states.
_TABLES = {3: (ROWS, PRESETS, _COMPONENT), 6: (ROWS_3D, PRESETS_3D, _COMPONENT_3D)}


def _table(n: int) -> tuple:
    if n not in _TABLES:
        raise InputError(f"stages control states of 3 (2D) or 6 (3D) components, not {n}")
    return _TABLES[n]


def rows_for(n: int) -> dict:
    """The named rows of stages on states of ``n`` components (3: 2D, 6: 3D)."""
    return _table(n)[0]


def presets_for(n: int) -> dict:
    """The presets of stages on states of ``n`` components (3: 2D, 6: 3D)."""
    return _table(n)[1]


def components_for(n: int) -> dict:
    """The component each single-component row of ``n``-component stages controls."""
    return _table(n)[2]


def is_stress_row(name: str) -> bool:
    """Whether row ``name`` (of either dimension) is a stress row."""
    return (ROWS.get(name) or ROWS_3D[name])[0]


def b_row(b: float) -> tuple[float, ...]:
    """The row (σ22 - σ33) - b (σ11 - σ33) of a 3D stage at constant b (its target is 0): b =
    (σ2 - σ3)/(σ1 - σ3) with the principal stresses σ1, σ2, σ3 along the axes 1, 2, 3."""
    return (-b, 1.0, b - 1.0, 0.0, 0.0, 0.0)


def check_b(value, where: str) -> float:
    """b as a number in [0, 1], or a one-line InputError."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
            or not 0.0 <= float(value) <= 1.0:
        raise InputError(f"{where}: b must be a number in [0, 1] (0: triaxial compression, 1: "
                         f"triaxial extension), got {value!r}")
    return float(value)


def row_coefficients(name: str, value, n: int) -> tuple[float, ...]:
    """The coefficients of row ``name`` on the ``n`` components (the ``b`` row's depend on its
    value)."""
    if name == "b":
        return b_row(check_b(value, "row b"))
    return rows_for(n)[name][1]


def check_row_names(names, n: int, where: str) -> None:
    """Refuse a row that the REV's dimension does not have (a 3D row in a 2D stage), and a
    stage that does not give one row per component: one-line InputError naming both."""
    table = rows_for(n)
    dim, other = ("2D", "3D") if n == 3 else ("3D", "2D")
    for name in names:
        if name not in table:
            hint = (f"; {name} is a {other} row" if name in rows_for(6 if n == 3 else 3) else "")
            raise InputError(f"{where}: unknown component {name!r} of a {dim} stage (rows: "
                             f"{', '.join(table)}){hint}")
    if len(names) != n:
        raise InputError(f"{where}: {len(names)} rows for a {dim} stage, which needs {n} (one per "
                         f"component {', '.join(_ORDER[n])})")


#: Increments of a stage whose strain rows do not move (a stress-controlled stage) by default.
DEFAULT_STEPS = 100


@dataclass(frozen=True)
class Stage:
    """One segment: ``rows`` maps each of three row names (:data:`ROWS`; six of :data:`ROWS_3D`
    in 3D) to a strain change, a stress target (:class:`Expression` of ``p0``) or ``"hold"``
    (the ``b`` row: to its value b); or, with ``iso`` set, an
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
        check_row_names(list(self.rows), state.n_components, f"stage {self.name!r}")
        names = component_order(list(self.rows))
        S = tuple(is_stress_row(n) for n in names)
        M = np.array([row_coefficients(n, self.rows[n], state.n_components) for n in names], float)
        values = []
        for n, row in zip(names, M):
            v = self.rows[n]
            if n == "b":
                v = 0.0
            elif isinstance(v, str) and v == "hold":
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
                             f"stress at p0 = {np.asarray(p0, float).tolist()} Pa "
                             f"({expression.fault({'p0': p0})})")
        return float(v) if v.ndim == 0 else v

    def n_steps(self) -> int:
        """``steps``, or the largest strain change over ``max_increment`` (default
        :data:`AXIAL_STEP`); :data:`DEFAULT_STEPS` when no strain row moves."""
        if self.steps is not None:
            return self.steps
        change = max([abs(v) for n, v in self.rows.items() if not is_stress_row(n)] + [0.0])
        if change == 0:
            return DEFAULT_STEPS
        return steps_for(change, self.max_increment or AXIAL_STEP, f"stage {self.name!r}: increments")


def component_order(names: list[str]) -> list[str]:
    """Rows in component order: a row on one component (``eps22``, ``sig22``) in that
    component's place, the combinations (``eps_v``, ``p``, ``q``) in the places left, in the
    order given. Both drivers then see one segment whatever order a program lists its rows in.
    Three names are a 2D stage's rows (components 11, 22, 12), six a 3D stage's (11, 22, 33,
    23, 13, 12).

    >>> component_order(["sig22", "eps12", "eps11"])
    ['eps11', 'sig22', 'eps12']
    >>> component_order(["eps_v", "eps11", "eps12"])
    ['eps11', 'eps_v', 'eps12']
    >>> component_order(["eps12", "p", "b", "eps11", "eps13", "eps23"])
    ['eps11', 'p', 'b', 'eps23', 'eps13', 'eps12']
    """
    order = _ORDER.get(len(names), _ORDER[3])
    component = _COMPONENT_3D if len(names) == 6 else _COMPONENT
    slots: list[str | None] = [None] * len(names)
    rest = []
    for name in names:
        comp = component.get(name)
        if comp is not None and comp in order and order.index(comp) < len(slots) and slots[order.index(comp)] is None:
            slots[order.index(comp)] = name
        else:
            rest.append(name)
    return [s if s is not None else rest.pop(0) for s in slots]
