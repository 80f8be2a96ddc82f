"""Task ``triaxial`` (YADE side, see :mod:`hmodel.dem.yade.scripts`): one triaxial test of a 3D
sample of spheres, requested by :func:`hmodel.dem.sample.run.run_test` with ``dim = 3``.

The control is that of the disk sample (:mod:`~hmodel.dem.yade.scripts.biaxial`: the same
servo, consolidation and shear, here on three axes); this script changes the scene and the
records.

Scene. A periodic cell (``O.periodic``) Lx x Ly x Lz of free spheres (6 degrees of freedom),
mass ``density`` 4/3 pi r^3, rotational inertia 2/5 m r^2 (YADE's own for a sphere). Contacts as
in the disk sample: linear springs kn, ks = kt_kn kn, or Hertz-Mindlin; Coulomb friction,
Cundall's damping.

Stress. The 3D Love-Weber stress, compression positive: sigma = (1/V) sum_c f (x) l, V = Lx Ly Lz,
computed as -utils.getStressAndTangent(V)[0]. Strains: logarithmic, compression positive, since
the end of the consolidation: eps_ii = ln(L_i0 / L_i).

Control (as the disk sample's, on three axes). Consolidation: the three normal stresses
servoed to p0, then one step at rest (see :meth:`_Triaxial.consolidate`). Shear along x (axis 1) at the constant compression rate ``strain_rate``
(extension: the opposite rate, when ``extension``); drained: sigma_22 and sigma_33 each held
at p0 by its own proportional-integral servo; undrained: velGrad_yy = velGrad_zz = r' with
(1 - r dt)(1 + r' dt)^2 = 1, so that the cell update h += dt L h keeps the volume to round-off.

Answer: rows ``[eps11, eps22, eps33, s11, s22, s33, s12, s13, s23, unbalanced, contacts,
sliding]`` (contacts: pairs with a non-negative overlap; sliding: the fraction of them whose
tangential force is at the Coulomb limit, |ft| >= (1 - 1e-6) tan(phi) fn), the consolidated and
final states (radii, positions wrapped into the cell, cell size, contacts
``[i, j, fn, ftx, fty, ftz, lx, ly, lz]``: f = fn e + ft the force on j by i, l the branch vector
from i to j across the periodic boundary where the contact is, e = l / |l|), time step, step
counts, wall times, YADE version.
"""

import math

try:  # pytest collecting the package's doctests
    from .biaxial import SLIDING, _Test, run as _run
    from .common import steps
except ImportError:  # in YADE: the scripts lie side by side in the working directory
    from biaxial import SLIDING, _Test, run as _run
    from common import steps


def _contacts(O, index):
    """[[i, j, fn, ftx, fty, ftz, lx, ly, lz, sliding]] of the contacts (overlap >= 0)."""
    h = O.cell.hSize
    rows = []
    for I in O.interactions:
        if not I.isReal or I.geom.penetrationDepth < 0:
            continue
        b1, b2 = O.bodies[I.id1].state.pos, O.bodies[I.id2].state.pos
        l = b2 + h * I.cellDist - b1
        f = I.phys.normalForce + I.phys.shearForce  # force on id2 by id1
        e = l / l.norm()
        fn = f.dot(e)
        ft = f - fn * e
        limit = I.phys.tangensOfFrictionAngle * I.phys.normalForce.norm()
        rows.append([index[I.id1], index[I.id2], fn, ft[0], ft[1], ft[2], l[0], l[1], l[2],
                     limit > 0 and I.phys.shearForce.norm() >= SLIDING * limit])
    return rows


class _Triaxial(_Test):
    """The sphere sample: free spheres in a 3D periodic cell, three controlled axes."""

    axes = 3

    def cell(self, size, r_max):
        return self.Matrix3(size[0], 0, 0, 0, size[1], 0, 0, 0, size[2])

    def force_scale(self, p0, r_max):
        """p0 d_max^2: a contact force [N] between the largest spheres at p0 [Pa], up to a factor
        of order one."""
        return p0 * (2.0 * r_max) ** 2

    def mass(self, r):
        return self.spec["density"] * self.size(r)

    def size(self, r):
        """Solid volume of a grain."""
        return 4.0 / 3.0 * math.pi * r ** 3

    def grain(self, utils, x, r, mat):
        b = utils.sphere(tuple(x), r, material=mat)
        m = self.mass(r)
        b.state.mass = m
        b.state.inertia = (0.4 * m * r * r,) * 3
        return b

    def volume(self):
        return self.O.cell.volume

    def consolidate(self):
        """The disk sample's consolidation, then one step at rest: YADE deforms the cell of a
        step by the velocity gradient of the step before, so without it the consolidation's
        last servo rate would deform the cell in the test's first step (a volume change of
        about 1e-9 in an undrained test, measured)."""
        out = super().consolidate()
        steps(self.O, 1)
        return out

    def row(self, h0):
        h = self.O.cell.hSize
        s, _ = self.utils.getStressAndTangent(self.volume() * 1.0, False)
        index = {bid: k for k, bid in enumerate(self.ids)}
        contacts = _contacts(self.O, index)
        n = len(contacts)
        sliding = sum(1 for c in contacts if c[-1]) / n if n else 0.0
        return ([math.log(h0[i, i] / h[i, i]) for i in range(3)]
                + [-s[0, 0], -s[1, 1], -s[2, 2], -0.5 * (s[0, 1] + s[1, 0]), -0.5 * (s[0, 2] + s[2, 0]),
                   -0.5 * (s[1, 2] + s[2, 1]), self.utils.unbalancedForce(), n, sliding])

    def undrained_rate(self, rate):
        """(1 - r dt)(1 + r' dt)^2 = 1: the lateral compression rate -r' keeping the volume."""
        return -(1.0 / math.sqrt(1.0 - rate * self.dt) - 1.0) / self.dt

    def state(self):
        O = self.O
        h = O.cell.hSize
        pos = []
        for bid in self.ids:
            p = O.cell.wrap(O.bodies[bid].state.pos)
            pos.append([p[0], p[1], p[2]])
        index = {bid: k for k, bid in enumerate(self.ids)}
        return {"cell": [h[0, 0], h[1, 1], h[2, 2]], "pos": pos, "radii": list(self.spec["radii"]),
                "contacts": [c[:-1] for c in _contacts(O, index)]}


def run(spec):
    """The answer to one request (see the module docstring)."""
    return _run(spec, _Triaxial)
