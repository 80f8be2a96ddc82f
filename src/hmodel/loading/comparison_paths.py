"""The standard named paths of the comparison of cell solvers, described as stages.

A recipe (``PathSpec``) names a path, the confining pressures of its material points and the
stages (:class:`~hmodel.loading.stages.Stage`) of its shear part for a given strain increment.
``standard_paths`` gives the paths of the comparison of cell solvers (report §3.1): isotropic
compression; drained biaxial at 100, 200 and 400 kPa; undrained biaxial; and three the report
never tried: an unloading-reloading cycle, oedometric compression and a path with rotating
principal strain axes (ε12 ≠ 0). ``run_recipe`` runs one on a ``Rev`` into a ``Recorder``, every
stage through the one segment runner; ``hmodel.compare`` runs each with two cell solvers and
measures their deviations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..rev import Rev, RevState
from .named_paths import consolidate
from .result import Recorder
from .segment import run_segment
from .stages import Stage


@dataclass(frozen=True)
class PathSpec:
    """A named comparison path: consolidation to ``p0`` then the stages ``shear(step)``
    returns for axial strain increments ``step``."""

    name: str
    p0: tuple[float, ...]
    shear: Callable[[float], tuple[Stage, ...]]
    in_report: bool


def _biaxial(axial: float, undrained: bool):
    rows = {"eps11": axial, "eps_v": 0.0, "eps12": 0.0} if undrained else \
        {"eps11": axial, "sig22": "hold", "eps12": 0.0}
    return lambda step: (Stage("shear", rows, max_increment=step),)


def _unload_reload(peak: float, unload: float, final: float):
    """Drained: to ``peak`` axial strain, back by ``unload``, then on to ``final``."""
    changes = (peak, -unload, final - (peak - unload))
    return lambda step: tuple(Stage("shear", {"eps11": d, "sig22": "hold", "eps12": 0.0},
                                    max_increment=step) for d in changes)


def _oedometric(axial: float):
    return lambda step: (Stage("shear", {"eps11": axial, "eps22": 0.0, "eps12": 0.0},
                               max_increment=step),)


def _rotation(amplitude: float, turns: float):
    """Isochoric deviatoric strain of constant rate whose principal axes rotate: one pure
    strain increment per stage, from one point of the strain circle to the next."""
    def stages(step):
        n = max(8, math.ceil(amplitude * 2 * math.pi * turns / step))
        t = np.linspace(0, 1, n + 1)
        ang = 2 * math.pi * turns * t
        ramp = np.minimum(1.0, 4 * t)  # reach the amplitude in the first quarter
        eps = np.column_stack([amplitude * ramp * np.cos(ang), -amplitude * ramp * np.cos(ang),
                               amplitude * ramp * np.sin(ang)])
        return tuple(Stage("shear", dict(zip(("eps11", "eps22", "eps12"), map(float, d))), steps=1)
                     for d in np.diff(eps, axis=0))
    return stages


def standard_paths(axial: float = 0.1) -> list[PathSpec]:
    """The comparison paths; ``axial`` scales the strains of the biaxial, unloading-reloading
    and oedometric paths."""
    return [
        PathSpec("isotropic", (4e5,), lambda step: (), True),
        PathSpec("drained", (1e5, 2e5, 4e5), _biaxial(axial, False), True),
        PathSpec("undrained", (2e5,), _biaxial(axial, True), True),
        PathSpec("unload-reload", (2e5,), _unload_reload(0.4 * axial, 0.05 * axial, 0.8 * axial), False),
        PathSpec("oedometric", (1e5,), _oedometric(0.2 * axial), False),
        PathSpec("rotation", (2e5,), _rotation(0.01, 1.0), False),
    ]


def run_recipe(rev: Rev, spec: PathSpec, step: float, iso_step: float, recorder: Recorder) -> RevState:
    """One recipe on ``rev``: consolidation to ``spec.p0`` in increments ``iso_step``, then its
    shear stages for increments ``step``, every state recorded; returns the final state. The
    axial strain at the end of the consolidation is ``recorder.meta["eps11_start"]``."""
    state = consolidate(rev, list(spec.p0), step=iso_step, recorder=recorder)
    recorder.meta["eps11_start"] = float(state.eps[0, 0])
    for stage in spec.shear(step):
        state = run_segment(rev, state, stage.segment(state), recorder).state
    return state
