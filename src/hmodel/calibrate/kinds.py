"""The kinds of test a calibration fits: what loading each is, in which dimension, and how the
H-model runs it for many parameter sets in one batched call."""

from __future__ import annotations

from collections.abc import Sequence
from enum import StrEnum

from ..cell import CellSolver
from ..errors import InputError
from ..loading import PathResult, run_biaxial, run_triaxial
from ..params import Params
from ..rev import Sphere


class Kind(StrEnum):
    """A kind of test: the 2D model's biaxial tests (``drained``, ``undrained``) and the 3D
    model's triaxial tests (``triaxial-drained``, ``triaxial-undrained``,
    ``triaxial-extension``), each after isotropic consolidation to p0.

    A member compares equal to its name (``Kind("drained") == "drained"``) and is written as it.
    """

    DRAINED = "drained"
    UNDRAINED = "undrained"
    TRIAXIAL_DRAINED = "triaxial-drained"
    TRIAXIAL_UNDRAINED = "triaxial-undrained"
    TRIAXIAL_EXTENSION = "triaxial-extension"

    @classmethod
    def parse(cls, name: str) -> Kind:
        """The kind named ``name`` (one-line InputError naming the kinds otherwise)."""
        try:
            return cls(name)
        except ValueError:
            raise InputError(f"test kind must be drained or undrained (2D) or {', '.join(k for k in cls if k.dim == 3)} "
                             f"(3D), got {name!r}") from None

    @property
    def dim(self) -> int:
        """2 for the 2D model's biaxial tests, 3 for the 3D model's triaxial ones."""
        return 3 if self.value.startswith("triaxial-") else 2

    @property
    def undrained(self) -> bool:
        return self in (Kind.UNDRAINED, Kind.TRIAXIAL_UNDRAINED)

    @property
    def extension(self) -> bool:
        """Axial unloading at constant radial stress (σ11 < σ22 = σ33)."""
        return self is Kind.TRIAXIAL_EXTENSION

    @property
    def sign(self) -> float:
        """The sign of the axial strain of the test (compression positive): −1 in extension."""
        return -1.0 if self.extension else 1.0

    @property
    def loading(self) -> str:
        """What the test is, in words."""
        return _LOADING[self]

    def run(self, sets: Sequence[Params], p0: Sequence[float], strain: float, *,
            solver: CellSolver | None, sphere: Sphere | None, step: float,
            iso_step: float) -> PathResult:
        """This test of one material point per parameter set ``sets[b]`` at ``p0[b]``, sheared
        to an axial strain of magnitude ``strain``, in one engine call; a point whose Newton
        fails is dropped (``meta["failed"]``), the others go on."""
        if self.dim == 2:
            return run_biaxial(list(sets), list(p0), strain, undrained=self.undrained, solver=solver,
                               iso_step=iso_step, step=step, drop_failed=True)
        return run_triaxial(list(sets), list(p0), strain, undrained=self.undrained,
                            extension=self.extension, sphere=sphere, solver=solver,
                            iso_step=iso_step, step=step, drop_failed=True)


_LOADING = {
    Kind.DRAINED: "drained biaxial compression (σ22 held at p0), 2D",
    Kind.UNDRAINED: "undrained (isochoric) biaxial compression, 2D",
    Kind.TRIAXIAL_DRAINED: "drained triaxial compression (σ22 = σ33 held at p0), 3D",
    Kind.TRIAXIAL_UNDRAINED: "undrained triaxial compression (εv = 0, ε22 = ε33), 3D",
    Kind.TRIAXIAL_EXTENSION: "drained triaxial extension (σ22 = σ33 held at p0, axial unloading), 3D",
}


def dimension(kinds: Sequence[Kind]) -> int:
    """The dimension of the model that runs all these kinds; kinds of both dimensions in one
    calibration are refused (one-line InputError)."""
    dims = {k.dim for k in kinds}
    if len(dims) > 1:
        two = sorted({k.value for k in kinds if k.dim == 2})
        three = sorted({k.value for k in kinds if k.dim == 3})
        raise InputError(f"the tests mix the 2D model's kinds ({', '.join(two)}) with the 3D "
                         f"model's ({', '.join(three)}): calibrate one model at a time")
    return dims.pop() if dims else 2
