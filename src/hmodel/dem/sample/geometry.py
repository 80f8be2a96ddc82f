"""The grains of a DEM sample, disks (``dim = 2``) or spheres (``dim = 3``): everything that
differs between a 2D and a 3D sample, in one place. The settings, the packing, the states, a
test's result and the run ask a sample's :class:`Grains` (:func:`grains`) rather than its
``dim``.

- :class:`Disks`: biaxial tests (YADE task ``biaxial``), stresses per unit thickness [N/m],
  masses of unit thickness;
- :class:`Spheres`: triaxial tests (YADE task ``triaxial``), stresses in Pa.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable

import numpy as np

from ...errors import InputError

#: Test kinds of a disk sample (biaxial).
KINDS = ("drained", "undrained")
#: Test kinds of a sphere sample (dim = 3), named as ``hmodel calibrate --data`` names them.
KINDS_3D = ("triaxial-drained", "triaxial-undrained", "triaxial-extension")
#: Radius distributions of a disk sample.
DISTRIBUTIONS = ("uniform", "equal-area")
#: Radius distributions of a sphere sample.
DISTRIBUTIONS_3D = ("uniform", "equal-volume")
#: Solid fraction of the densest sphere packing: a sphere sample's cell is never smaller than
#: its solid volume over this.
DENSEST_3D = math.pi / math.sqrt(18.0)
#: Solid fraction of the densest disk packing (hexagonal): a disk sample's cell is never
#: smaller than its solid area over this.
DENSEST_2D = math.pi / (2.0 * math.sqrt(3.0))
#: Columns of a contact row: grain indices, normal force (compression positive), tangential
#: force f.(e_y, -e_x), branch vector l from i to j (across the periodic boundary if need be);
#: f is the force on j by i, e = l / |l|.
CONTACT_COLUMNS = ("i", "j", "fn", "ft", "lx", "ly")
#: Columns of a contact row of a sphere sample: fn as for disks, the tangential force vector
#: ft = f - fn e, the branch vector l from i to j.
CONTACT_COLUMNS_3D = ("i", "j", "fn", "ftx", "fty", "ftz", "lx", "ly", "lz")
#: Columns of the test CSV: the ``--data`` format of ``hmodel calibrate`` (eps11, q, eps_v, p),
#: then the coordination number and the sliding fraction (ignored by ``--data``).
CSV_COLUMNS = ("eps11", "q", "eps_v", "p", "coordination", "sliding")
#: Columns of a recorded row (``rows`` of the npz file); contacts: YADE's real interactions,
#: sliding: the fraction of the contacts at the Coulomb limit.
ROW_COLUMNS = ("eps11", "eps22", "s11", "s22", "s12", "unbalanced", "contacts", "sliding")
#: Columns of a sphere sample's test CSV: the triaxial ``--data`` format (eps_a, q, eps_v, p),
#: then the coordination number, the sliding fraction and the stress tensor [Pa].
CSV_COLUMNS_3D = ("eps_a", "q", "eps_v", "p", "coordination", "sliding",
                  "sig11", "sig22", "sig33", "sig12", "sig13", "sig23")
#: Columns of a sphere sample's recorded row (``rows`` of the npz file); contacts: pairs in
#: contact, sliding: the fraction of them at the Coulomb limit.
ROW_COLUMNS_3D = ("eps11", "eps22", "eps33", "s11", "s22", "s33", "s12", "s13", "s23",
                  "unbalanced", "contacts", "sliding")


class Grains:
    """What a sample of these grains is (class attributes) and how its measures are computed."""

    #: Dimension: the sample's ``dim``.
    dim: int
    #: The grains in messages, and the command-line option that counts them.
    noun: str
    option: str
    #: The sample in messages.
    sample: str
    #: The YADE task that runs a test (:mod:`hmodel.dem.yade`).
    task: str
    #: Its test kinds, radius distributions (and the note an error about them adds).
    kinds: tuple[str, ...]
    distributions: tuple[str, ...]
    distribution_note: str = ""
    #: Solid fraction of the densest packing.
    densest: float
    #: The axial strain's column in the test CSV.
    axial: str
    #: Columns of a recorded row, of the test CSV and of a contact row.
    row_columns: tuple[str, ...]
    csv_columns: tuple[str, ...]
    contact_columns: tuple[str, ...]

    def check_count(self, n: int) -> None:
        """Refuse too few grains before the periodic check (InputError)."""

    def solid(self, r):
        """Solid area (disks) or volume (spheres) of grains of radius ``r``."""
        raise NotImplementedError

    def mean_solid(self, a: float, b: float, distribution: str) -> float:
        """The expected solid of one grain, radii in [a, b] drawn by ``distribution``."""
        raise NotImplementedError

    def graded_radii(self, a: float, b: float, u: np.ndarray) -> np.ndarray:
        """Radii of the distribution other than ``uniform`` from uniform numbers ``u``: the
        inverse of its CDF."""
        raise NotImplementedError

    def lattice(self, n: int) -> tuple[int, ...]:
        """Sites per axis of the lattice that holds ``n`` grains of the initial gas."""
        raise NotImplementedError

    def forces(self, fn: np.ndarray, e: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """Contact forces (c, dim) from the normal forces, the unit branch vectors and the
        contact rows (their tangential force columns)."""
        raise NotImplementedError

    def table(self, test) -> dict[str, np.ndarray]:
        """The test CSV's columns (:attr:`csv_columns`) of a test's recorded rows."""
        raise NotImplementedError

    def draw_sample(self, tests: dict[str, dict], final: Callable, table: Callable,
                    path: "str | os.PathLike") -> None:
        """``sample.png`` of the tests whose records are ``tests`` (by name): ``final(name)`` is a
        test's final :class:`~hmodel.dem.sample.state.SampleState` and ``table(name)`` its CSV's
        columns (None for a file removed by hand: the test is left out)."""
        raise NotImplementedError


class Disks(Grains):
    """A 2D sample: disks, biaxial tests."""

    dim = 2
    noun = "disks"
    option = "--disks"
    sample = "disk sample (--dim 2)"
    task = "biaxial"
    kinds = KINDS
    distributions = DISTRIBUTIONS
    densest = DENSEST_2D
    axial = "eps11"
    row_columns = ROW_COLUMNS
    csv_columns = CSV_COLUMNS
    contact_columns = CONTACT_COLUMNS

    def check_count(self, n: int) -> None:
        if n < 20:
            raise InputError(f"--disks must be at least 20, got {n}")

    def solid(self, r):
        return math.pi * r ** 2

    def mean_solid(self, a: float, b: float, distribution: str) -> float:
        # mean of r^2: r uniform in [a, b], or density ~ r^-2 (equal-area), whose mean is ab
        r2 = (a * a + a * b + b * b) / 3.0 if distribution == "uniform" or a == b else a * b
        return math.pi * r2

    def graded_radii(self, a: float, b: float, u: np.ndarray) -> np.ndarray:
        return 1.0 / (1.0 / a - u * (1.0 / a - 1.0 / b))  # equal-area: pdf ~ r^-2

    def lattice(self, n: int) -> tuple[int, ...]:
        nx = math.ceil(math.sqrt(n))
        return (nx, math.ceil(n / nx))

    def forces(self, fn: np.ndarray, e: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        t = np.stack([e[:, 1], -e[:, 0]], axis=1)
        return fn[:, None] * e + contacts[:, 3, None] * t

    def table(self, test) -> dict[str, np.ndarray]:
        """q = s11 - s22, p = (s11 + s22) / 2."""
        e1, e2 = test.column("eps11"), test.column("eps22")
        s1, s2 = test.column("s11"), test.column("s22")
        return {"eps11": e1, "q": s1 - s2, "eps_v": e1 + e2, "p": 0.5 * (s1 + s2),
                "coordination": 2.0 * test.column("contacts") / len(test.final.radii),
                "sliding": test.column("sliding")}

    def draw_sample(self, tests: dict[str, dict], final: Callable, table: Callable,
                    path: "str | os.PathLike") -> None:
        """The final packing of every test with its force chains."""
        from .draw import draw_sample

        states = []
        for n, r in tests.items():
            st = final(n)
            if st is not None:
                states.append((self.title(r, st), st))
        draw_sample(states, path)

    def title(self, rec: dict, st) -> str:
        """A packing's panel title: the test and its final state's porosity and coordination."""
        return (f"{rec['kind']} {rec['p0'] / 1e3:g} kPa, {self.axial} = {100 * rec['axial_strain']:g} %: "
                f"n = {st.porosity:.3f}, z = {st.coordination:.2f}")


class Spheres(Grains):
    """A 3D sample: spheres, triaxial tests."""

    dim = 3
    noun = "spheres"
    option = "--spheres"
    sample = "sphere sample (--dim 3)"
    task = "triaxial"
    kinds = KINDS_3D
    distributions = DISTRIBUTIONS_3D
    distribution_note = " with spheres"
    densest = DENSEST_3D
    axial = "eps_a"
    row_columns = ROW_COLUMNS_3D
    csv_columns = CSV_COLUMNS_3D
    contact_columns = CONTACT_COLUMNS_3D

    def solid(self, r):
        return 4.0 / 3.0 * math.pi * r ** 3

    def mean_solid(self, a: float, b: float, distribution: str) -> float:
        if distribution == "uniform" or a == b:
            r3 = (a ** 3 + a * a * b + a * b * b + b ** 3) / 4.0  # mean of r^3, r uniform in [a, b]
        else:
            r3 = 2.0 * (b - a) / (a ** -2 - b ** -2)  # mean of r^3, density ~ r^-3 in [a, b]
        return 4.0 / 3.0 * math.pi * r3

    def graded_radii(self, a: float, b: float, u: np.ndarray) -> np.ndarray:
        # equal-volume: pdf ~ r^-3, inverse of the CDF (a^-2 - r^-2) / (a^-2 - b^-2) (derived here)
        return (a ** -2 - u * (a ** -2 - b ** -2)) ** -0.5

    def lattice(self, n: int) -> tuple[int, ...]:
        nx = round(n ** (1.0 / 3.0))
        nx += nx ** 3 < n
        return (nx, nx, math.ceil(n / nx ** 2))

    def forces(self, fn: np.ndarray, e: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        return fn[:, None] * e + contacts[:, 3:6]

    def table(self, test) -> dict[str, np.ndarray]:
        """q = s11 - (s22 + s33) / 2, p = tr(s) / 3, and the stress tensor."""
        e = [test.column(f"eps{i}{i}") for i in (1, 2, 3)]
        s = {c: test.column("s" + c) for c in ("11", "22", "33", "12", "13", "23")}
        return {"eps_a": e[0], "q": s["11"] - 0.5 * (s["22"] + s["33"]), "eps_v": e[0] + e[1] + e[2],
                "p": (s["11"] + s["22"] + s["33"]) / 3.0,
                "coordination": 2.0 * test.column("contacts") / len(test.final.radii),
                "sliding": test.column("sliding"), **{"sig" + c: v for c, v in s.items()}}

    def draw_sample(self, tests: dict[str, dict], final: Callable, table: Callable,
                    path: "str | os.PathLike") -> None:
        """The tests' curves."""
        from .draw import draw_curves

        draw_curves([(n, table(n)) for n in tests], path)


#: The grains a sample can be made of.
GRAINS: tuple[Grains, ...] = (Disks(), Spheres())


def grains(dim) -> Grains:
    """The grains of a sample of dimension ``dim`` (InputError for another)."""
    for g in GRAINS:
        if g.dim == dim:
            return g
    raise InputError(f"--dim must be 2 (disks) or 3 (spheres), got {dim}")
