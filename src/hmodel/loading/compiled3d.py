"""Compiled loading segments of the 3D REV (issue 34): :class:`hmodel.rev.Rev3D` on the kernels
of :mod:`hmodel.loading.compiled`.

Those kernels are written for n components: with n = 6 every trial is the 3D REV's fused step
(:func:`hmodel.rev.kernels3d.bihex_trial`: localization of the 6-component strain increment on
each bi-hexagon's three axes, the two hexagons' closed-form increments sharing δl1, averaging to
the 6-component stress over the macro volume V0 det(I - ε)), the same operations as
:meth:`Rev3D.step`. The rest is shared with 2D: the one Newton of :mod:`hmodel.loading.newton`
on six components (a finite-difference tangent is 7 trials), its event loop, the per-point
batched kernel (points in parallel for B > 1, each with its own parameter set), the hand-back
of an increment the kernel cannot converge to the generic driver, and the dropping of failed
points. What is 3D here is the packing of the kernel's inputs (:func:`kernel_inputs3d`): one
geometry shared by all parameter sets (the sphere's frames and weights), and each set's packed
closed-form parameters. Results equal the generic driver's to Newton's tolerance
(``tests/test_compiled3d.py``).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..rev import Rev3D, RevState
from .compiled import CompiledSegment, isotropic_steps

__all__ = ["CompiledSegment3D", "isotropic_steps3d", "kernel_inputs3d"]


def kernel_inputs3d(rev: Rev3D) -> tuple[np.ndarray, np.ndarray]:
    """(geo, p) of the kernel for a 3D REV: the cells' projector rows and weighted dyads
    (1, C, 36) (:meth:`Rev3D.geometry`, the same for every parameter set) and each set's
    packed closed-form parameters (K, P). The 3D trial is the closed form's: a learned 3D
    cell's kernel is refused (one-line :class:`~hmodel.errors.InputError`), not ignored."""
    if any(k.learned for k in rev.kernels):
        raise InputError("the compiled 3D trial applies the closed-form bi-hexagon; a learned 3D "
                         "cell runs on the generic driver (run_segment(..., compiled=False))")
    return (np.ascontiguousarray(rev.geometry()[None]),
            np.ascontiguousarray(np.stack([k.params for k in rev.kernels])))


class CompiledSegment3D(CompiledSegment):
    """The compiled backend of :func:`~hmodel.loading.segment.run_segment` for a
    :class:`~hmodel.rev.Rev3D`: :class:`~hmodel.loading.compiled.CompiledSegment` (``run``
    -> records (k, B, 16), ``state``, ``snapshot``, ``restore``, the hand-back and
    ``failures``) with the 3D REV's kernel inputs."""

    inputs = staticmethod(kernel_inputs3d)


def isotropic_steps3d(rev: Rev3D, state: RevState, step: float, p0: np.ndarray, n_max: int,
                      failed: np.ndarray) -> tuple[RevState, np.ndarray, np.ndarray]:
    """:func:`~hmodel.loading.compiled.isotropic_steps` of a 3D REV: equal increments ``step``
    of ε11, ε22, ε33 until each point's mean stress would reach its ``p0``."""
    return isotropic_steps(rev, state, step, p0, n_max, failed, inputs=kernel_inputs3d)
