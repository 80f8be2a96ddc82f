"""The kinds of test a calibration fits, one class each: what loading a test is, in which
dimension, how the H-model runs it for many parameter sets in one batched call, and what it
measures that the model must reproduce.

A new kind of test (an undrained p–q path, an oedometer, a lateral stress) is one subclass of
:class:`Kind` here: its name, dimension and loading in words, its ``run`` and, where they differ
from the defaults, its ``observables`` and ``curves``. Listed in :data:`BUILTIN`, it is named on
the command line (``--data oedometer:100kPa:FILE``); a subclass defined elsewhere is given to a
:class:`~hmodel.calibrate.data.Test` as an instance (``Test(Oedometer(), p0, ...)``), as emcee
takes its moves.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from ..cell import CellSolver
from ..errors import InputError
from ..loading import PathResult, run_biaxial, run_triaxial
from ..params import Params
from ..rev import Sphere

#: The curves a calibration's model predicts for every test (the columns of its runs and the
#: attributes of a :class:`~hmodel.calibrate.model.Prediction` and of a measured test): what a
#: kind's :meth:`~Kind.observables` chooses from.
OBSERVABLES = ("q", "eps_v")


class _Kinds(type):
    """The class :class:`Kind` as the enumeration of the built-in kinds: iterating over it gives
    them, and ``Kind.TRIAXIAL_DRAINED`` is the built-in named ``triaxial-drained``."""

    def __iter__(cls):
        return iter(BUILTIN)

    def __len__(cls) -> int:
        return len(BUILTIN)

    def __getattr__(cls, member: str):  # only for names the class itself does not have
        # (looked up while the kinds' classes are made, before BUILTIN exists)
        for kind in globals().get("BUILTIN", ()):
            if kind.name == member:
                return kind
        raise AttributeError(f"type object {cls.__name__!r} has no attribute {member!r}")


class Kind(str, metaclass=_Kinds):
    """A kind of test, always after isotropic consolidation to p0: the 2D model's biaxial tests
    (``drained``, ``undrained``) and the 3D model's triaxial tests (``triaxial-drained``,
    ``triaxial-undrained``, ``triaxial-extension``) are built in.

    A kind is the string of its name: it compares equal to it (``Kind("drained") ==
    "drained"``) and is written as it. ``Kind(name)`` is the built-in kind of that name (the
    same object each time: ``Kind("drained") is Kind.DRAINED``), ``Kind(kind)`` a kind itself.

    A subclass sets ``value`` (its name), ``dim``, ``loading`` and, for a test that holds the
    volume or unloads axially, ``undrained`` or ``extension``, and implements :meth:`run`
    (given ``radial``, how a drained triaxial test holds its sides, where it takes that keyword).
    """

    #: the kind's name, as on the command line and in ``calibration.json``
    value: ClassVar[str]
    #: 2 for the 2D model's tests, 3 for the 3D model's
    dim: ClassVar[int]
    #: what the test is, in words
    loading: ClassVar[str]
    #: the specimen's volume held (εv = 0 by the test's definition)
    undrained: ClassVar[bool] = False
    #: axial unloading at constant radial stress (σ11 < σ22 = σ33): the axial strain decreases
    extension: ClassVar[bool] = False

    def __new__(cls, name: str | None = None) -> Kind:
        if cls is Kind:
            if isinstance(name, Kind):
                return name
            for kind in BUILTIN:
                if kind == name:
                    return kind
            raise ValueError(f"{name!r} is not a valid Kind")
        if name is not None and name != cls.value:
            raise ValueError(f"{cls.__name__} is the kind {cls.value!r}, not {name!r}")
        return super().__new__(cls, cls.value)

    @classmethod
    def parse(cls, name: str) -> Kind:
        """The kind named ``name``, or ``name`` itself where it is a kind (one-line InputError
        naming the built-in kinds otherwise)."""
        try:
            return Kind(name)
        except ValueError:
            two = " or ".join(k for k in BUILTIN if k.dim == 2)
            three = ", ".join(k for k in BUILTIN if k.dim == 3)
            raise InputError(f"test kind must be {two} (2D) or {three} (3D), got {name!r}") from None

    @property
    def name(self) -> str:
        """The kind's name as an attribute of :class:`Kind`, as an enumeration member's
        (``TRIAXIAL_DRAINED``)."""
        return self.value.upper().replace("-", "_")

    @property
    def sign(self) -> float:
        """The sign of the axial strain of the test (compression positive): −1 in extension."""
        return -1.0 if self.extension else 1.0

    def observables(self) -> tuple[str, ...]:
        """What the test measures and the model must reproduce against the axial strain, in
        the order of the residuals (among :data:`OBSERVABLES`): q and εv."""
        return ("q", "eps_v")

    def run(self, sets: Sequence[Params], p0: Sequence[float], strain: float, *,
            solver: CellSolver | None, sphere: Sphere | None, step: float,
            iso_step: float, radial: str | None = None) -> PathResult:
        """This test of one material point per parameter set ``sets[b]`` at ``p0[b]``, sheared
        to an axial strain of magnitude ``strain``, in one engine call (``radial``: how a drained
        triaxial test holds its sides, :func:`~hmodel.loading.run_triaxial`; 2D tests have one
        lateral strain); a point whose Newton
        fails is dropped (``meta["failed"]``), the others go on. The result's rows are those
        of a loading path: stages ``consolidation`` then ``shear``, the columns eps11, q and
        eps_v among them."""
        raise NotImplementedError(f"kind {self} does not say how it runs")

    def curves(self, res: PathResult, b: int, test, dropped: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """q and εv since consolidation of material point ``b`` of :meth:`run`'s result ``res``,
        at ``test``'s axial strains. A point ``dropped`` where its Newton failed keeps its rows
        up to there: NaN beyond the last strain it reached."""
        point, stage = res["point"], res["stage"]
        mine = point == b
        cons = np.flatnonzero(mine & (stage == "consolidation"))
        if not len(cons):
            return np.full(len(test.eps11), np.nan), np.full(len(test.eps11), np.nan)
        cons = cons[-1]
        shear = mine & (stage == "shear")
        # the axial strain's magnitude since consolidation (increasing in extension too)
        e = self.sign * np.concatenate([[0.0], res["eps11"][shear] - res["eps11"][cons]])
        q = np.interp(test.strain, e, np.concatenate([[res["q"][cons]], res["q"][shear]]))
        ev = np.interp(test.strain, e, np.concatenate([[0.0], res["eps_v"][shear] - res["eps_v"][cons]]))
        if dropped:
            beyond = test.strain > e[-1]
            q[beyond] = ev[beyond] = np.nan
        return q, ev

    @property
    def builtin(self) -> bool:
        """Whether this is the instance of :data:`BUILTIN` (the one ``Kind(name)`` returns)."""
        return any(self is k for k in BUILTIN)

    def __repr__(self) -> str:
        return f"Kind({self.value!r})" if self.builtin else f"{type(self).__name__}()"

    def __reduce__(self):
        # a built-in comes back as the one instance of its name (``is`` comparisons hold across
        # processes); another kind as a new instance of its class
        return (Kind, (self.value,)) if self.builtin else (type(self), ())


class _Biaxial(Kind):
    """The 2D model's plane-strain biaxial compression."""

    dim = 2

    def run(self, sets, p0, strain, *, solver, sphere, step, iso_step, radial=None) -> PathResult:
        return run_biaxial(list(sets), list(p0), strain, undrained=self.undrained, solver=solver,
                           iso_step=iso_step, step=step, drop_failed=True)


class _Triaxial(Kind):
    """The 3D model's triaxial test along axis 1, the shear strains held."""

    dim = 3

    def run(self, sets, p0, strain, *, solver, sphere, step, iso_step, radial=None) -> PathResult:
        return run_triaxial(list(sets), list(p0), strain, undrained=self.undrained,
                            extension=self.extension, radial=radial, sphere=sphere, solver=solver,
                            iso_step=iso_step, step=step, drop_failed=True)


class Drained(_Biaxial):
    value = "drained"
    loading = "drained biaxial compression (σ22 held at p0), 2D"


class _Isochoric:
    """An undrained test: εv is zero by its definition, so only q is measured."""

    undrained = True

    def observables(self) -> tuple[str, ...]:
        return ("q",)


class Undrained(_Isochoric, _Biaxial):
    value = "undrained"
    loading = "undrained (isochoric) biaxial compression, 2D"


class TriaxialDrained(_Triaxial):
    value = "triaxial-drained"
    loading = "drained triaxial compression (σ22 = σ33 held at p0), 3D"


class TriaxialUndrained(_Isochoric, _Triaxial):
    value = "triaxial-undrained"
    loading = "undrained triaxial compression (εv = 0, ε22 = ε33), 3D"


class TriaxialExtension(_Triaxial):
    value = "triaxial-extension"
    loading = "drained triaxial extension (σ22 = σ33 held at p0, axial unloading), 3D"
    extension = True


#: The kinds named on the command line, in the order a calibration runs them.
BUILTIN: tuple[Kind, ...] = (Drained(), Undrained(), TriaxialDrained(), TriaxialUndrained(),
                             TriaxialExtension())


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
