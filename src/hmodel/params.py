"""Material and discretization parameters of the H-model, validated in one place.

Defaults are Veylon (2017), report Table 1.1. Angles are stored in radians; the CLI and
:meth:`Params.from_strings` take them in degrees, as the report does.

>>> p = Params.from_strings({"alpha0": "50", "n_theta": "72"})
>>> round(p.alpha0_deg, 6), p.n_theta, p.kt
(50.0, 72, 100000000.0)
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

from .errors import InputError

VOLUMES = ("hexagon", "rectangle", "box", "hexagon-consistent")
SLIDING_RHS = ("report", "equilibrium")
#: Contact laws of the cells' grains: the published linear springs (kn, kt) or Hertz-Mindlin
#: spheres (shear_modulus, poisson), docs/mechanisms.md.
CONTACTS = ("linear", "hertz-mindlin")
#: What becomes of a cell whose contact opened: nothing (published: it stays force-free until
#: its grains meet again) or a new cell at contact in the space the old one held.
RENEWALS = ("none", "rebirth", "mix")
#: Contacts between the lateral grains of a bi-hexagon's two hexagons (3D only): ignored
#: (published closure) or frictionless normal contacts of the cell's law (docs/mechanisms.md).
CROSS_CONTACTS = ("none", "frictionless")
#: What lateral strain a bi-hexagon's two lateral lengths follow: each its own direction's
#: (affine, published) or both the mean of the two (the strain's part that is axisymmetric
#: about the cell's axis), docs/mechanisms.md; the 2D H-cell's one lateral length is either.
LATERALS = ("affine", "axisymmetric")
ANGLE_PARAMS = ("phi_g", "alpha0", "beta_omega")

#: Units shown in tables, figures and ``--help``.
UNITS = {
    "kn": "N/m", "kt_kn": "-", "phi_g": "deg", "alpha0": "deg", "alpha_omega": "-",
    "beta_omega": "deg", "n_theta": "-", "radius": "m", "volume": "-", "g2": "-",
    "sliding_rhs": "-", "alpha0_spread": "-", "contact": "-", "shear_modulus": "Pa",
    "poisson": "-", "renewal": "-", "cross_contacts": "-", "lateral": "-",
}


@dataclass(frozen=True)
class Params:
    """Immutable parameter set of one H-model material.

    Attributes
    ----------
    kn : float
        Normal contact stiffness [N/m] (eq. 1.3).
    kt_kn : float
        Ratio kt/kn of tangential to normal stiffness [-].
    phi_g : float
        Inter-granular friction angle [rad], in (0, pi/2).
    alpha0 : float
        Initial opening angle of the H-cells [rad], in (pi/6, pi/2).
    alpha_omega, beta_omega : float
        Fabric anisotropy of eq. 1.17: intensity in [0, 1] and major direction [rad].
    n_theta : int
        Number of cell directions theta_i = i*pi/n_theta.
    radius : float
        Grain radius r [m]; stresses do not depend on it.
    volume : str
        Meso-volume option (eqs. 1.18-1.21): hexagon, rectangle, box, hexagon-consistent.
    g2 : int
        Closure of eq. 1.5: 0 (Nicot & Darve 2011) or 1 (the later version).
    sliding_rhs : str
        Right-hand side lambda of eq. 1.10 when sliding. ``report`` is the corrected eq. 1.10
        lambda = xi (g2 + sin a)(tan phi N1 - T1)/kn, as in the report's code;
        ``equilibrium`` is lambda = (g2 + sin a)(xi tan phi N1 - T1)/kn, which keeps grain 2
        in equilibrium (eq. 1.5) when the contact slides with T1 < 0. Both agree for xi = +1.
    alpha0_spread : float
        Spread of the opening angles across directions, in [0, 1): the cells' initial α0 are
        the n_theta mid-quantiles of a uniform distribution on α0 ± alpha0_spread ·
        min(α0 − 30°, 90° − α0), one per direction in an order uncorrelated with θ
        (:func:`hmodel.rev.directions.opening_angles`); 0 is the H-model of one α0.
    contact : str
        Contact law (:data:`CONTACTS`): ``linear`` (published: kn, kt) or ``hertz-mindlin``
        (spheres of radius r, shear modulus and Poisson ratio of the grains; kn and kt_kn are
        then not used).
    shear_modulus : float
        Grains' shear modulus G [Pa] of the Hertz-Mindlin law.
    poisson : float
        Grains' Poisson ratio ν [-] of the Hertz-Mindlin law, in [0, 0.5).
    renewal : str
        Fate of a cell whose contact opened (:data:`RENEWALS`): ``none`` (published) or
        ``rebirth`` (reborn at contact, force-free, in the space it held) or ``mix``
        (``volume="hexagon"``: reborn at contact, force-free, at the REV's mean box l1·l2, 3D
        l1·l2·l3).
    cross_contacts : str
        Contacts between the lateral grains of hexagon A and hexagon B of the 3D model's
        bi-hexagon (:data:`CROSS_CONTACTS`): ``none`` (published closure: ignored) or
        ``frictionless`` (normal force of the cell's contact law, coupling the two hexagons);
        no meaning in 2D.
    lateral : str
        What a bi-hexagon's lateral lengths l2 and l3 follow (:data:`LATERALS`): ``affine``
        (published: each the strain along its own direction, eq. 1.1 lifted) or
        ``axisymmetric`` (both the mean of the two: the cell's lateral grains turn about its
        axis, so a cell at contact can follow any strain); one value per batch. The 2D H-cell
        has one lateral length, the mean of itself: both values are the published 2D model.
    """

    kn: float = 2.0e8
    kt_kn: float = 0.5
    phi_g: float = math.radians(30.0)
    alpha0: float = math.radians(45.0)
    alpha_omega: float = 0.0
    beta_omega: float = 0.0
    n_theta: int = 360
    radius: float = 1.0
    volume: str = "hexagon"
    g2: int = 0
    sliding_rhs: str = "report"
    alpha0_spread: float = 0.0
    contact: str = "linear"
    shear_modulus: float = 29.0e9
    poisson: float = 0.2
    renewal: str = "none"
    cross_contacts: str = "none"
    lateral: str = "affine"

    def __post_init__(self) -> None:
        self.validate()

    # -- derived quantities -------------------------------------------------------------
    @property
    def kt(self) -> float:
        """Tangential stiffness kt = kt_kn * kn [N/m]."""
        return self.kt_kn * self.kn

    @property
    def tan_phi(self) -> float:
        return math.tan(self.phi_g)

    @property
    def alpha0_deg(self) -> float:
        return math.degrees(self.alpha0)

    @property
    def alpha0_half_width(self) -> float:
        """Half-width h [rad] of the cells' initial opening angles, α0 ± h: h = alpha0_spread ·
        min(α0 − 30°, 90° − α0), so that every cell stays in the H-cell's (30°, 90°)."""
        return self.alpha0_spread * min(self.alpha0 - math.pi / 6, math.pi / 2 - self.alpha0)

    @property
    def l10(self) -> float:
        """Initial cell length l1 = d2 + 2 d1 cos(alpha0) with d1 = d2 = 2r (eq. 1.2)."""
        return 2 * self.radius * (1 + 2 * math.cos(self.alpha0))

    @property
    def l20(self) -> float:
        """Initial cell length l2 = 2 d1 sin(alpha0) with d1 = 2r (eq. 1.2)."""
        return 4 * self.radius * math.sin(self.alpha0)

    # -- validation ---------------------------------------------------------------------
    def validate(self) -> None:
        """Raise :class:`InputError` naming the first invalid parameter."""
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float) and not math.isfinite(v):
                raise InputError(f"parameter {f.name} must be finite, got {v}")
        if self.kn <= 0:
            raise InputError(f"parameter kn must be positive, got {self.kn}")
        if self.kt_kn <= 0:
            raise InputError(f"parameter kt_kn must be positive, got {self.kt_kn}")
        if not 0 < self.phi_g < math.pi / 2:
            raise InputError(f"parameter phi_g must lie in (0, 90) deg, got {math.degrees(self.phi_g):g}")
        if not math.pi / 6 < self.alpha0 < math.pi / 2:
            raise InputError(f"parameter alpha0 must lie in (30, 90) deg, got {math.degrees(self.alpha0):g}")
        if not 0 <= self.alpha_omega <= 1:
            raise InputError(f"parameter alpha_omega must lie in [0, 1], got {self.alpha_omega}")
        if not 0 <= self.alpha0_spread < 1:
            raise InputError(f"parameter alpha0_spread must lie in [0, 1), got {self.alpha0_spread}")
        if int(self.n_theta) != self.n_theta or self.n_theta < 1:
            raise InputError(f"parameter n_theta must be a positive integer, got {self.n_theta}")
        if self.radius <= 0:
            raise InputError(f"parameter radius must be positive, got {self.radius}")
        if self.volume not in VOLUMES:
            raise InputError(f"parameter volume must be one of {', '.join(VOLUMES)}, got {self.volume!r}")
        if self.g2 not in (0, 1):
            raise InputError(f"parameter g2 must be 0 or 1, got {self.g2}")
        if self.sliding_rhs not in SLIDING_RHS:
            raise InputError(
                f"parameter sliding_rhs must be one of {', '.join(SLIDING_RHS)}, got {self.sliding_rhs!r}")
        if self.contact not in CONTACTS:
            raise InputError(f"parameter contact must be one of {', '.join(CONTACTS)}, got {self.contact!r}")
        if self.shear_modulus <= 0:
            raise InputError(f"parameter shear_modulus must be positive (Pa), got {self.shear_modulus}")
        if not 0 <= self.poisson < 0.5:
            raise InputError(f"parameter poisson must lie in [0, 0.5), got {self.poisson}")
        if self.renewal not in RENEWALS:
            raise InputError(f"parameter renewal must be one of {', '.join(RENEWALS)}, got {self.renewal!r}")
        if self.renewal == "mix" and self.volume != "hexagon":
            raise InputError(f"renewal=mix is derived for volume=hexagon (the cells' box area l1*l2 "
                             f"follows exp(-tr eps) there), got volume={self.volume!r}")
        if self.cross_contacts not in CROSS_CONTACTS:
            raise InputError(f"parameter cross_contacts must be one of {', '.join(CROSS_CONTACTS)}, "
                             f"got {self.cross_contacts!r}")
        if self.lateral not in LATERALS:
            raise InputError(f"parameter lateral must be one of {', '.join(LATERALS)}, got {self.lateral!r}")

    # -- conversions --------------------------------------------------------------------
    def with_(self, **changes) -> "Params":
        """A copy with some parameters changed (angles in radians)."""
        return replace(self, **changes)

    def to_dict(self, degrees: bool = True) -> dict:
        """Plain dict, angles in degrees by default (for CSV/JSON metadata)."""
        d = asdict(self)
        if degrees:
            for name in ANGLE_PARAMS:
                d[name] = math.degrees(d[name])
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Params":
        """Inverse of :meth:`to_dict` (angles in degrees)."""
        return cls.from_strings({k: repr(v) if isinstance(v, float) else str(v) for k, v in d.items()})

    @classmethod
    def from_strings(cls, values: dict[str, str], base: "Params | None" = None) -> "Params":
        """Build from ``NAME -> text`` pairs as given on the command line (angles in degrees)."""
        known = {f.name: f for f in fields(cls)}
        changes: dict = {}
        for name, text in values.items():
            if name not in known:
                raise InputError(f"unknown parameter {name!r} (known: {', '.join(known)})")
            changes[name] = _convert(name, text, known[name].type)
        return replace(base or cls(), **changes)

    @classmethod
    def parse_assignments(cls, items: list[str] | None, base: "Params | None" = None) -> "Params":
        """Parse ``["kn=2e8", "alpha0=50"]`` (the ``--param`` option)."""
        values: dict[str, str] = {}
        for item in items or []:
            name, sep, text = item.partition("=")
            if not sep or not name.strip() or not text.strip():
                raise InputError(f"--param expects NAME=VALUE, got {item!r}")
            values[name.strip()] = text.strip()
        return cls.from_strings(values, base)


#: Parameters every material point of one batch shares (the REV's directions, lengths and
#: localization); the others may differ from point to point (:func:`parse_point_assignments`).
SHARED = ("n_theta", "radius", "volume", "lateral")


def check_batch(sets) -> tuple[Params, ...]:
    """The parameter sets of a batch of material points, one per point (or one for all),
    refused with a one-line error when they differ in a shared parameter (:data:`SHARED`)."""
    sets = (sets,) if isinstance(sets, Params) else tuple(sets)
    if not sets or not all(isinstance(s, Params) for s in sets):
        raise InputError("a batch needs one or more Params, one per material point")
    for name in SHARED:
        values = {getattr(s, name) for s in sets}
        if len(values) > 1:
            raise InputError(f"parameter {name} is shared by the material points of one run, "
                             f"got {', '.join(map(str, sorted(values, key=str)))}")
    return sets


def parse_point_assignments(items: list[str] | None, base: Params | None = None) -> list[Params]:
    """``--param`` with comma lists: ``["phi_g=25,35", "alpha0=45,55", "kn=2e8"]`` gives one
    Params per listed value (two here), single values shared by all; lists of unequal lengths
    (other than 1) are a one-line error, as are lists of a shared parameter (:data:`SHARED`).

    >>> [round(p.alpha0_deg) for p in parse_point_assignments(["phi_g=25,35", "alpha0=45,55"])]
    [45, 55]
    """
    columns: dict[str, list[str]] = {}
    for item in items or []:
        name, sep, text = item.partition("=")
        if not sep or not name.strip() or not text.strip():
            raise InputError(f"--param expects NAME=VALUE or NAME=V1,V2,..., got {item!r}")
        values = [v.strip() for v in text.split(",")]
        if any(not v for v in values):
            raise InputError(f"--param {name.strip()}: empty value in {text!r}")
        if len(values) > 1 and name.strip() in SHARED:
            raise InputError(f"parameter {name.strip()} is shared by the material points of one run: "
                             f"give one value, got {text!r}")
        columns[name.strip()] = values
    lengths = sorted({len(v) for v in columns.values()} - {1})
    if len(lengths) > 1:
        raise InputError("--param lists must have equal lengths (or one value): got "
                         + ", ".join(f"{k}: {len(v)}" for k, v in columns.items() if len(v) > 1))
    n = lengths[0] if lengths else 1
    return [Params.from_strings({k: v[i if len(v) > 1 else 0] for k, v in columns.items()}, base)
            for i in range(n)]


def _convert(name: str, text: str, typ) -> object:
    if typ in ("str", str):
        return str(text)
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise InputError(f"parameter {name} expects a number, got {text!r}") from None
    if typ in ("int", int):
        if not value.is_integer():
            raise InputError(f"parameter {name} expects an integer, got {text!r}")
        return int(value)
    if name in ANGLE_PARAMS:
        value = math.radians(value)
    return value
