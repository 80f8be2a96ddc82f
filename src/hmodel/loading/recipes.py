"""Loading recipes: the standard named paths, each a consolidation then shear segments.

A recipe (``PathSpec``) names a path, the confining pressures of its material points and how
its shear part is built from segments on a ``Rev``. ``standard_paths`` gives the paths of the
comparison of cell solvers (report §3.1): isotropic compression; drained biaxial at 100, 200
and 400 kPa; undrained biaxial; and three the report never tried: an unloading-reloading
cycle, oedometric compression and a path with rotating principal strain axes (ε12 ≠ 0).
``run_recipe`` runs one on a ``Rev`` into a ``Recorder``; ``hmodel.compare`` runs each with two
cell solvers and measures their deviations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..rev import Rev, RevState
from .paths import biaxial_segment, consolidate, strain_path
from .segment import Segment, run_segment
from .result import Recorder


@dataclass(frozen=True)
class PathSpec:
    """A named comparison path: consolidation to ``p0`` then ``shear`` segments."""

    name: str
    p0: tuple[float, ...]
    build: Callable  # (rev, consolidated state, step, recorder) -> final state
    in_report: bool


def _biaxial(axial: float, undrained: bool):
    def build(rev, state, step, rec):
        n = max(1, math.ceil(axial / step - 1e-9))
        return run_segment(rev, state, biaxial_segment(state, axial, n, undrained), rec).state
    return build


def _unload_reload(peak: float, unload: float, final: float):
    def build(rev, state, step, rec):
        p = state.sig[:, 1]
        for target in (peak, peak - unload, final):
            d = target - (state.eps[0, 0] - rec.meta["eps11_start"])
            n = max(1, math.ceil(abs(d) / step - 1e-9))
            state = run_segment(rev, state, biaxial_segment(state, d, n, lateral_stress=p), rec).state
        return state
    return build


def _oedometric(axial: float):
    def build(rev, state, step, rec):
        n = max(1, math.ceil(axial / step - 1e-9))
        return run_segment(rev, state, Segment.components("EEE", [axial, 0.0, 0.0], n, "shear"), rec).state
    return build


def _rotation(amplitude: float, turns: float):
    """Isochoric deviatoric strain of constant rate whose principal axes rotate."""
    def build(rev, state, step, rec):
        n = max(8, math.ceil(amplitude * 2 * math.pi * turns / step))
        t = np.linspace(0, 1, n + 1)[1:]
        ang = 2 * math.pi * turns * t
        e0 = state.eps[0]
        ramp = np.minimum(1.0, 4 * t)  # reach the amplitude in the first quarter
        eps = np.column_stack([e0[0] + amplitude * ramp * np.cos(ang), e0[1] - amplitude * ramp * np.cos(ang),
                               e0[2] + amplitude * ramp * np.sin(ang)])
        for row in eps:
            state = strain_path(rev, row[None, :], state=state)
            rec.record(state, "shear")
        return state
    return build


def standard_paths(axial: float = 0.1) -> list[PathSpec]:
    """The comparison paths; ``axial`` scales the strains of the biaxial, unloading-reloading
    and oedometric paths."""
    return [
        PathSpec("isotropic", (4e5,), lambda rev, s, step, rec: s, True),
        PathSpec("drained", (1e5, 2e5, 4e5), _biaxial(axial, False), True),
        PathSpec("undrained", (2e5,), _biaxial(axial, True), True),
        PathSpec("unload-reload", (2e5,), _unload_reload(0.4 * axial, 0.05 * axial, 0.8 * axial), False),
        PathSpec("oedometric", (1e5,), _oedometric(0.2 * axial), False),
        PathSpec("rotation", (2e5,), _rotation(0.01, 1.0), False),
    ]


def run_recipe(rev: Rev, spec: PathSpec, step: float, iso_step: float, recorder: Recorder) -> RevState:
    """One recipe on ``rev``: consolidation to ``spec.p0`` in increments ``iso_step``, then its
    shear segments in increments ``step``, every state recorded; returns the final state. The
    axial strain at the end of the consolidation is ``recorder.meta["eps11_start"]``."""
    state = consolidate(rev, list(spec.p0), step=iso_step, recorder=recorder)
    recorder.meta["eps11_start"] = float(state.eps[0, 0])
    return spec.build(rev, state, step, recorder)
