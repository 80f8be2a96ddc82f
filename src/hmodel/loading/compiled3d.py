"""Compiled loading segments of the 3D REV (:class:`hmodel.rev.Rev3D`): the kernels of
:mod:`hmodel.loading.compiled`, which are the 2D REV's too.

Those kernels are written for n components and take each REV's kernel inputs
(:meth:`hmodel.rev.batch.RevBatch.kernel_inputs`): for the 3D REV one geometry shared by all
parameter sets (each bi-hexagon's projector rows and weighted dyads) and each set's packed
closed-form parameters, with which every trial is the 3D REV's fused step
(:func:`hmodel.rev.kernels3d.bihex_trial`: the same operations as :meth:`Rev3D.step`). Nothing
here is 3D any more: the names below are the general ones under the names the 3D path had.
Results equal the generic driver's to Newton's tolerance (``tests/test_compiled3d.py``).
"""

from __future__ import annotations

import numpy as np

from ..rev import Rev3D
from .compiled import CompiledSegment

__all__ = ["CompiledSegment3D", "kernel_inputs3d"]

#: :class:`~hmodel.loading.compiled.CompiledSegment`, which runs any REV
CompiledSegment3D = CompiledSegment


def kernel_inputs3d(rev: Rev3D) -> tuple[np.ndarray, np.ndarray]:
    """The 3D REV's kernel inputs (:meth:`Rev3D.kernel_inputs`): (1, C, 36) and (K, P)."""
    return rev.kernel_inputs()
