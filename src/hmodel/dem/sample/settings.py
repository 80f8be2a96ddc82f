"""The settings of a DEM sample and its tests (everything but a test's kind and p0), and the
strain rate and inertial number they set.

Units: lengths in m, kn in N/m, pressures in N/m for disks (Pa for unit thickness) and Pa for
spheres, the grains' shear modulus in Pa, angles in degrees.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ...errors import InputError
from ...limits import check_memory
from .geometry import (  # noqa: F401 (KINDS...DENSEST_3D: importers of their first home)
    DENSEST_2D,
    DENSEST_3D,
    DISTRIBUTIONS,
    DISTRIBUTIONS_3D,
    KINDS,
    KINDS_3D,
    Grains,
    grains,
)

#: A sample's cell edge must hold this many of its largest diameters, so that no grain reaches
#: its own periodic image and the cell is more than a few grains.
MIN_DIAMETERS_3D = 3.0
#: Contact laws of a sample: linear springs kn, kt (the H-model's), or Hertz-Mindlin (stiffnesses
#: growing with the normal force, from the grains' shear modulus and Poisson ratio).
CONTACTS = ("linear", "hertz-mindlin")
#: Memory of one grain of a test [bytes], an upper estimate: YADE holds about 7 KiB per sphere
#: with its contacts (measured: 40,000 spheres touching 6 others each, 282 MB over YADE's own
#: 245 MB); the request and the two states answered (radii, centres, contact rows), as lists and
#: JSON text in YADE and here, then arrays and the figure, about as much again; a margin over that.
GRAIN_BYTES = 24 * 2**10
#: Memory of one recorded row of a test [bytes]: a dozen numbers as lists and JSON text in YADE
#: and here, an array and CSV text, with a margin.
ROW_BYTES = 4 * 2**10


def kinds(dim: int) -> tuple[str, ...]:
    """The test kinds of a sample of dimension ``dim``."""
    return grains(dim).kinds


@dataclass(frozen=True)
class SampleSettings:
    """Everything that defines a sample and its tests, except the tests' kind and p0.

    Attributes
    ----------
    disks : int
        Number of disks (spheres when ``dim`` is 3).
    radius : float
        Mean of r_min and r_max [m].
    radius_ratio : float
        r_max / r_min (1: monodisperse).
    distribution : str
        ``uniform`` (radius uniform in [r_min, r_max]) or ``equal-area`` (density proportional
        to r^-2: every radius interval holds the same solid area); with spheres ``uniform`` or
        ``equal-volume`` (density proportional to r^-3: the same solid volume).
    kn : float
        Normal contact stiffness [N/m] of the linear law (unused by Hertz-Mindlin).
    kt_kn : float
        kt / kn of the linear law (unused by Hertz-Mindlin).
    contact : str
        The contact law (:data:`CONTACTS`): ``linear`` (springs kn, kt_kn kn, Coulomb friction)
        or ``hertz-mindlin`` (YADE's Hertz-Mindlin law from ``shear_modulus`` and ``poisson``,
        Coulomb friction).
    shear_modulus : float or None
        The grains' shear modulus G [Pa] (Hertz-Mindlin only; their Young's modulus is
        E = 2 G (1 + poisson)).
    poisson : float or None
        The grains' Poisson ratio, in (-1, 0.5) (Hertz-Mindlin only).
    phi_g : float
        Contact friction angle during the test [deg].
    compaction_friction : float or None
        Contact friction angle during the consolidation [deg]; None: 0 (the densest sample),
        or phi_g when ``porosity`` is given.
    porosity : float or None
        Target porosity: the consolidation starts with ``compaction_friction`` and lowers the
        friction (tan phi x 0.9 per step, each followed by a new equilibrium at p0) until the
        porosity is at most this.
    density : float
        Grain density [kg/m^3] (disks of unit thickness, or spheres).
    axial_strain : float
        Axial strain of the test (logarithmic).
    rows : int
        Rows of the CSV after its first (eps11 = 0): one every axial_strain / rows.
    inertial_number : float
        Sets the axial strain rate, strain_rate = I / (d_mean sqrt(density / p0)).
    strain_rate : float or None
        The axial strain rate [1/s], instead of ``inertial_number``.
    seed : int
        Seed of the radii and initial positions.
    damping : float
        Cundall's non-viscous damping of NewtonIntegrator.
    dt_safety : float
        Time step = dt_safety sqrt(m_min / kn).
    tol_stress, tol_unbalanced : float
        The consolidation ends when |s_ii - p0| <= tol_stress p0 and the unbalanced-force ratio
        is at most tol_unbalanced.
    compaction_inertial_number : float
        The largest strain rate of the consolidation, as an inertial number at p0.
    period : int
        Time steps between two servo updates.
    check : int
        Time steps between two checks of the consolidation's criterion.
    gain, gain_i : float
        Proportional and integral gains of the servo (dimensionless, relative to the affine
        stiffness).
    lateral_rate_factor : float
        The drained lateral strain rate is at most this times the axial one.
    max_steps : int
        Time steps allowed for the consolidation.
    timeout : float
        Wall-clock limit of one test's YADE run [s].
    dim : int
        2: disks, biaxial tests (:data:`KINDS`); 3: spheres, triaxial tests (:data:`KINDS_3D`).
    """

    disks: int = 2000
    radius: float = 1.0
    radius_ratio: float = 2.0
    distribution: str = "uniform"
    kn: float = 2.0e8
    kt_kn: float = 0.5
    phi_g: float = 30.0
    compaction_friction: float | None = None
    porosity: float | None = None
    density: float = 2650.0
    axial_strain: float = 0.1
    rows: int = 100
    inertial_number: float = 1e-4
    strain_rate: float | None = None
    seed: int = 0
    damping: float = 0.2
    dt_safety: float = 0.3
    tol_stress: float = 1e-3
    tol_unbalanced: float = 1e-3
    compaction_inertial_number: float = 1e-2
    period: int = 5
    check: int = 50
    gain: float = 0.5
    gain_i: float = 0.1
    lateral_rate_factor: float = 10.0
    max_steps: int = 5_000_000
    timeout: float = 3600.0
    dim: int = 2
    contact: str = "linear"
    shear_modulus: float | None = None
    poisson: float | None = None

    def __post_init__(self) -> None:
        def finite(name):
            v = getattr(self, name)
            return v is not None and isinstance(v, (int, float)) and math.isfinite(v)

        for name in ("radius", "radius_ratio", "kn", "kt_kn", "density", "axial_strain",
                     "inertial_number", "tol_stress", "tol_unbalanced",
                     "compaction_inertial_number", "gain", "lateral_rate_factor", "timeout"):
            if not (finite(name) and getattr(self, name) > 0):
                raise InputError(f"{option_name(name)} must be a positive number, got {getattr(self, name)}")
        g = self.grains  # refuses another dim
        g.check_count(self.disks)
        if self.radius_ratio < 1:
            raise InputError(f"--radius-ratio must be >= 1 (r_max / r_min), got {self.radius_ratio}")
        if self.distribution not in g.distributions:
            raise InputError(f"--distribution must be one of {', '.join(g.distributions)}"
                             f"{g.distribution_note}, got {self.distribution!r}")
        self._check_periodic()
        if not (finite("phi_g") and 0 < self.phi_g < 90):
            raise InputError(f"--phi-g must lie in (0, 90) degrees, got {self.phi_g}")
        if self.compaction_friction is not None and not (
                finite("compaction_friction") and 0 <= self.compaction_friction < 90):
            raise InputError(f"--compaction-friction must lie in [0, 90) degrees, got "
                             f"{self.compaction_friction}")
        if self.porosity is not None and not (finite("porosity") and 0 < self.porosity < 1):
            raise InputError(f"--porosity must lie in (0, 1), got {self.porosity}")
        if self.porosity is not None and self.compaction_friction == 0:
            raise InputError("--porosity lowers the friction from --compaction-friction, which "
                             "must then be above 0")
        if self.axial_strain >= 1:
            raise InputError(f"--axial-strain must be below 1, got {self.axial_strain}")
        if self.seed < 0:
            raise InputError(f"--seed must be >= 0, got {self.seed}")
        if self.rows < 1:
            raise InputError(f"--rows must be a positive integer, got {self.rows}")
        if self.strain_rate is not None and not (finite("strain_rate") and self.strain_rate > 0):
            raise InputError(f"--strain-rate must be a positive number, got {self.strain_rate}")
        self._check_contact()
        if not (0 <= self.damping < 1 and 0 < self.dt_safety <= 1 and 0 < self.gain_i
                and self.period >= 1 and self.check >= 1 and self.max_steps >= 1):
            raise InputError(f"invalid numerical settings of the DEM sample: {self}")

    def _check_contact(self) -> None:
        """The contact law and its grain constants: G and nu with Hertz-Mindlin, neither with
        the linear law (whose kn, kt_kn would silently replace them)."""
        if self.contact not in CONTACTS:
            raise InputError(f"--contact must be one of {', '.join(CONTACTS)}, got {self.contact!r}")
        hertz = ("shear_modulus", "poisson")
        if self.contact == "linear":
            given = [option_name(n) for n in hertz if getattr(self, n) is not None]
            if given:
                verb = "set" if len(given) > 1 else "sets"
                raise InputError(f"{' and '.join(given)} {verb} the Hertz-Mindlin law: add --contact "
                                 f"hertz-mindlin (the linear law's stiffness is --kn, --kt-kn)")
            return
        missing = [option_name(n) for n in hertz if getattr(self, n) is None]
        if missing:
            raise InputError(f"--contact hertz-mindlin needs the grains' {' and '.join(missing)} "
                             f"(quartz: --shear-modulus 29GPa --poisson 0.2)")
        g, nu = self.shear_modulus, self.poisson
        if not (isinstance(g, (int, float)) and math.isfinite(g) and g > 0):
            raise InputError(f"--shear-modulus must be a positive number [Pa], got {g}")
        if not (isinstance(nu, (int, float)) and math.isfinite(nu) and -1 < nu < 0.5):
            raise InputError(f"--poisson must lie in (-1, 0.5), got {nu}")

    @property
    def young(self) -> float | None:
        """The grains' Young's modulus E = 2 G (1 + nu) [Pa] (Hertz-Mindlin; None with the
        linear law)."""
        if self.contact != "hertz-mindlin":
            return None
        return 2.0 * self.shear_modulus * (1.0 + self.poisson)

    def _check_periodic(self) -> None:
        """A sample's cell at its densest (solid fraction :data:`DENSEST_3D`, or
        :data:`DENSEST_2D` for disks) must be :data:`MIN_DIAMETERS_3D` largest diameters wide;
        the expected solid volume (area) is used, so the check does not depend on the seed."""
        a, b, g = self.r_min, self.r_max, self.grains
        need = math.ceil((MIN_DIAMETERS_3D * 2.0 * b) ** g.dim * g.densest
                         / g.mean_solid(a, b, self.distribution))
        if self.disks < need:
            raise InputError(f"{g.option} {self.disks} is too small a sample to be periodic: its "
                             f"densest cell is narrower than {MIN_DIAMETERS_3D:g} largest "
                             f"diameters; use at least {need} {g.noun} (or a smaller --radius-ratio)")

    def estimated_bytes(self) -> float:
        """Estimated memory [bytes] of one test: its grains (:data:`GRAIN_BYTES`) and its
        ``rows`` + 1 recorded rows (:data:`ROW_BYTES`)."""
        return float(self.disks) * GRAIN_BYTES + (float(self.rows) + 1.0) * ROW_BYTES

    def check_size(self) -> None:
        """Refuse (:class:`~hmodel.limits.WorkTooLarge`) a test whose :meth:`estimated_bytes` exceeds
        the memory budget, before any grain is drawn or YADE started."""
        g = self.grains
        check_memory(self.estimated_bytes(), f"a test of {self.disks:,} {g.noun} ({g.option}) and "
                                        f"{self.rows + 1:,} rows (--rows)")

    @property
    def grains(self) -> Grains:
        """Its grains (:mod:`~hmodel.dem.sample.geometry`): what differs between disks and spheres."""
        return grains(self.dim)

    @property
    def r_min(self) -> float:
        return 2.0 * self.radius / (1.0 + self.radius_ratio)

    @property
    def r_max(self) -> float:
        return self.radius_ratio * self.r_min

    @property
    def friction_compact(self) -> float:
        """Friction angle of the consolidation [deg]."""
        if self.compaction_friction is not None:
            return self.compaction_friction
        return self.phi_g if self.porosity is not None else 0.0

    def to_dict(self) -> dict:
        return asdict(self)


def option_name(name: str) -> str:
    """The command-line option of a setting: ``radius_ratio`` -> ``--radius-ratio``."""
    return "--" + name.replace("_", "-")


def strain_rate(settings: SampleSettings, p0: float, d_mean: float) -> float:
    """Axial strain rate of a test at p0 [1/s]."""
    if settings.strain_rate is not None:
        return settings.strain_rate
    return settings.inertial_number / (d_mean * math.sqrt(settings.density / p0))


def inertial_number(rate: float, d_mean: float, density: float, p: float) -> float:
    """I = rate d_mean sqrt(density / p)."""
    return rate * d_mean * math.sqrt(density / p) if p > 0 else math.inf
