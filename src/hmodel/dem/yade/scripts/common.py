"""What every YADE scene of hmodel shares (YADE side, see :mod:`hmodel.dem.yade.scripts`)."""

import math

#: A Hertz-Mindlin sample's time step is set by the contact stiffness at this many times the
#: force scale p0 d_max^(dim - 1) of its largest grains, about ten times their mean contact force
#: at p0: the stiffness grows only as the cube root of the force, so the margin costs little.
HERTZ_FORCE_MARGIN = 4.0


def stiffness(w, kn, kt_kn, frictionless=()):
    """The contact physics: kn and ks = kt_kn kn for every pair (``w`` is ``yade.wrapper``);
    the pairs of material ids in ``frictionless`` without friction, the others with the smaller
    friction angle of their two materials (YADE's default).

    MatchMakers, because YADE's default, the harmonic mean 2 E Ra Rb / (Ra + Rb), gives kn = E r
    only for equal radii r, while the H-model's kn is a contact constant.
    """
    extra = {}
    if frictionless:
        extra["frictAngle"] = w.MatchMaker(matches=[(a, b, 0.0) for a, b in frictionless], algo="min")
    return w.Ip2_FrictMat_FrictMat_FrictPhys(kn=w.MatchMaker(algo="val", val=kn),
                                             ks=w.MatchMaker(algo="val", val=kt_kn * kn), **extra)


def steps(O, n):
    """n time steps (O.step() in a loop: O.run(n, True) adds a fixed wait to every call,
    longer than the few steps a balanced cell needs)."""
    for _ in range(n):
        O.step()


def contact_law(w, spec, r_max):
    """(Young's modulus and Poisson ratio of the grains' FrictMat, Ip2 functor, Law2 functor) of a
    sample's contact law, ``spec["contact"]`` (``linear`` where absent).

    linear: :func:`stiffness` and Coulomb friction (Law2_ScGeom_FrictPhys_CundallStrack), the
    material's moduli unused. hertz-mindlin: YADE's Hertz-Mindlin law from the grains' E and nu
    (Ip2_FrictMat_FrictMat_MindlinPhys, Law2_ScGeom_MindlinPhys_Mindlin): for grains of radii
    r1, r2 at overlap d, fn = 4/3 E* sqrt(R d) d, kn = dfn/dd = 2 E* sqrt(R d),
    ks = 8 G* sqrt(R d), E* = E / (2 (1 - nu^2)), G* = G / (2 (2 - nu)), R = r1 r2 / (r1 + r2),
    and Coulomb friction; no viscous damping (Cundall's damping as with linear contacts).
    """
    if spec.get("contact", "linear") == "hertz-mindlin":
        return (spec["young"], spec["poisson"], w.Ip2_FrictMat_FrictMat_MindlinPhys(),
                w.Law2_ScGeom_MindlinPhys_Mindlin())
    kn = spec["kn"]
    return kn / r_max, spec["kt_kn"], stiffness(w, kn, spec["kt_kn"]), w.Law2_ScGeom_FrictPhys_CundallStrack()


def hertz_stiffness(young, poisson, r_eff, force):
    """The normal stiffness dfn/dd of YADE's Hertz law (:func:`contact_law`) at the normal force
    ``force``: fn = kno d^1.5, kno = 4/3 E* sqrt(R), so kn = 1.5 kno^(2/3) fn^(1/3)."""
    kno = 4.0 / 3.0 * young / (2.0 * (1.0 - poisson ** 2)) * math.sqrt(r_eff)
    return 1.5 * kno ** (2.0 / 3.0) * force ** (1.0 / 3.0)


def time_step_stiffness(spec, r_max, force_scale):
    """The normal stiffness that sets a sample's time step: kn (linear), or the Hertz stiffness
    between two of the largest grains at :data:`HERTZ_FORCE_MARGIN` times ``force_scale``."""
    if spec.get("contact", "linear") == "hertz-mindlin":
        return hertz_stiffness(spec["young"], spec["poisson"], 0.5 * r_max, HERTZ_FORCE_MARGIN * force_scale)
    return spec["kn"]
