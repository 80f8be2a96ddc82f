"""Task ``biaxial`` (YADE side, see :mod:`hmodel.dem.yade.scripts`): one biaxial test of a DEM
sample, requested by :func:`hmodel.dem.sample.run.run_test`.

Scene. A periodic cell (``O.periodic``) of size Lx x Ly x Lz holding disks: spheres in the
plane z = Lz/2 whose z translation and x, y rotations are blocked (``blockedDOFs = "zXY"``),
so they move in the plane and spin about z; Lz = 8 r_max, so a disk never meets its own image
along z and the cell's z size never changes. Mass per unit thickness ``density`` pi r^2
(a disk of unit thickness), rotational inertia m r^2 / 2. Contacts: linear springs kn,
ks = kt_kn kn for every pair (:func:`~hmodel.dem.yade.scripts.common.stiffness`), Coulomb friction
(Law2_ScGeom_FrictPhys_CundallStrack), Cundall's non-viscous damping ``damping``; or, with
``contact`` ``hertz-mindlin``, YADE's Hertz-Mindlin law from the grains' ``young`` and
``poisson`` (:func:`~hmodel.dem.yade.scripts.common.contact_law`; between disks, the law of the
spheres they are). Time step ``dt_safety`` sqrt(m_min / kn), kn the linear one or the Hertz
stiffness at a few times the largest grains' contact force at p0
(:func:`~hmodel.dem.yade.scripts.common.time_step_stiffness`).

Stress. 2D Love-Weber stress per unit area of the cell, compression positive:
sigma = (1/A) sum_c f (x) l, f the force on j by i and l the branch vector from i to j (across the
periodic boundary where the contact is), A = Lx Ly; computed as -utils.getStressAndTangent(A)[0]
(YADE's stress is tension positive). Strains: logarithmic, compression positive,
eps11 = ln(Lx0 / Lx), eps22 = ln(Ly0 / Ly), eps_v = ln(A0 / A), since the end of the
consolidation.

Control. The cell deforms through ``O.cell.velGrad`` (diagonal, zz = 0), the disks follow the
affine field (``Cell.homoDeform``). A stress-controlled direction i is servoed every ``period``
steps: strain rate = gain (sigma_ii - goal) / (C_iiii period dt) (C: the affine tangent
stiffness of ``utils.getStressAndTangent``, an upper bound of the sample's), clipped to
``rate_max``.

1. Consolidation: both directions servoed to p0 with friction ``phi_compact`` until
   |sigma_ii - p0| <= ``tol_stress`` p0 and the unbalanced-force ratio <= ``tol_unbalanced``,
   checked every ``check`` steps; more than ``max_steps`` steps: status ``no-equilibrium``.
   With a target ``porosity``, each such equilibrium whose porosity is above the target is
   followed by tan(friction) x 0.9 (0 below 0.01) in the material and every contact, until an
   equilibrium at or below the target; status ``error`` when the first equilibrium is already
   below the target (too loose a target for this friction) or the frictionless one above it.
   The friction is then set to phi_g in the material and every contact.
2. Shear: velGrad_xx = -rate (constant axial strain rate), and either sigma_22 servoed to p0
   by a proportional-integral servo (the integral term adds ``gain_i`` u per update, u the
   proportional term without gain; both clipped to ``lateral_rate_factor`` rate) (drained), or
   velGrad_yy = rate / (1 - rate dt) (undrained: the cell update h += dt L h then keeps the area
   constant to round-off). A row is recorded at every ``axial_strain / rows`` of axial strain
   (a whole number of steps each).

Answer: rows ``[eps11, eps22, s11, s22, s12, unbalanced, contacts, sliding]`` (sliding: the
fraction of the contacts with a non-negative overlap whose shear force is on the Coulomb limit,
as in :mod:`~hmodel.dem.yade.scripts.triaxial`), the consolidated
and final states (radii, positions wrapped into the cell, cell size, contacts
``[i, j, fn, ft, lx, ly]`` with l the branch vector from i to j, fn compression positive),
time step, step counts, wall times, YADE version.
"""

import math
import time

try:  # pytest collecting the package's doctests
    from .common import contact_law, steps, time_step_stiffness
except ImportError:  # in YADE: the scripts lie side by side in the working directory
    from common import contact_law, steps, time_step_stiffness


#: The Coulomb limit is reached when |ft| is at least this fraction of tan(phi) fn: the law
#: scales the shear force back onto the limit, so a sliding contact sits on it to round-off.
SLIDING = 1.0 - 1e-6


def sliding_fraction(O):
    """The fraction of the contacts (overlap >= 0) whose shear force is on the Coulomb limit."""
    n = sliding = 0
    for I in O.interactions:
        if not I.isReal or I.geom.penetrationDepth < 0:
            continue
        n += 1
        limit = I.phys.tangensOfFrictionAngle * I.phys.normalForce.norm()
        sliding += limit > 0 and I.phys.shearForce.norm() >= SLIDING * limit
    return sliding / n if n else 0.0


def _state(O, utils, ids, radii):
    """The sample's state: cell size, wrapped positions, radii, contacts."""
    h = O.cell.hSize
    lx, ly = h[0, 0], h[1, 1]
    pos = []
    for bid in ids:
        p = O.cell.wrap(O.bodies[bid].state.pos)
        pos.append([p[0], p[1]])
    index = {bid: k for k, bid in enumerate(ids)}
    rows = []
    for I in O.interactions:
        if not I.isReal or I.geom.penetrationDepth < 0:
            continue
        i, j = index[I.id1], index[I.id2]
        shift = h * I.cellDist
        b1, b2 = O.bodies[I.id1].state.pos, O.bodies[I.id2].state.pos
        l = b2 + shift - b1
        f = I.phys.normalForce + I.phys.shearForce  # force on id2 by id1
        norm = math.hypot(l[0], l[1])
        ex, ey = l[0] / norm, l[1] / norm
        fn = f[0] * ex + f[1] * ey
        ft = f[0] * ey - f[1] * ex
        rows.append([i, j, fn, ft, l[0], l[1]])
    return {"cell": [lx, ly], "pos": pos, "radii": list(radii), "contacts": rows}


class _Test:
    """The scene of one request and its stress, servo and strain-rate control; the control is
    written for ``axes`` stress-controlled axes (2 here, 3 in the sphere sample of
    :mod:`~hmodel.dem.yade.scripts.triaxial`, which overrides the scene's grains and records)."""

    axes = 2

    def __init__(self, spec):
        from yade import O, utils
        from yade import Matrix3
        import yade.wrapper as w

        self.O, self.utils, self.Matrix3, self.spec = O, utils, Matrix3, spec
        O.reset()
        radii = spec["radii"]
        r_max, r_min = max(radii), min(radii)
        O.periodic = True
        O.cell.hSize = self.cell(spec["cell"], r_max)
        young, poisson, ip2, law2 = contact_law(w, spec, r_max)
        mat = O.materials.append(w.FrictMat(young=young, poisson=poisson,
                                            density=spec["density"], frictionAngle=spec["phi_compact"]))
        self.ids = [O.bodies.append(self.grain(utils, x, r, mat)) for x, r in zip(spec["pos"], radii)]
        O.engines = [w.ForceResetter(),
                     w.InsertionSortCollider([w.Bo1_Sphere_Aabb()], verletDist=0.1 * r_min),
                     w.InteractionLoop([w.Ig2_Sphere_Sphere_ScGeom()], [ip2], [law2]),
                     w.NewtonIntegrator(damping=spec["damping"], gravity=(0, 0, 0))]
        kn = time_step_stiffness(spec, r_max, self.force_scale(spec["p0"], r_max))
        O.dt = spec["dt_safety"] * math.sqrt(self.mass(r_min) / kn)
        self.dt = O.dt
        self.solid = sum(self.size(r) for r in radii)

    def cell(self, size, r_max):
        """The cell's hSize: Lx x Ly, and Lz = 8 r_max so that a disk never meets its image."""
        return self.Matrix3(size[0], 0, 0, 0, size[1], 0, 0, 0, 8.0 * r_max)

    def force_scale(self, p0, r_max):
        """p0 d_max: a contact force [N] between the largest disks at p0 [N/m], up to a factor
        of order one."""
        return p0 * 2.0 * r_max

    def mass(self, r):
        """A disk of unit thickness."""
        return self.spec["density"] * math.pi * r * r

    def size(self, r):
        """Solid area of a grain."""
        return math.pi * r * r

    def grain(self, utils, x, r, mat):
        """A disk: a sphere in the plane z = Lz/2 that moves in the plane and spins about z."""
        b = utils.sphere((x[0], x[1], 0.5 * self.O.cell.hSize[2, 2]), r, material=mat)
        b.state.blockedDOFs = "zXY"
        m = self.mass(r)
        b.state.mass = m
        b.state.inertia = (0.5 * m * r * r,) * 3
        return b

    def volume(self):
        """The cell's area (2D)."""
        h = self.O.cell.hSize
        return h[0, 0] * h[1, 1]

    def porosity(self):
        return 1.0 - self.solid / self.volume()

    def normal(self):
        """([sigma_ii], [C_iiii]) over the controlled axes: stress (compression positive) and
        affine stiffness."""
        s, c = self.utils.getStressAndTangent(self.volume() * 1.0, False)
        return [-s[i, i] for i in range(self.axes)], [c[i, i] for i in range(self.axes)]

    def row(self, h0):
        """A recorded row, strains since the cell h0 (see the module docstring)."""
        h = self.O.cell.hSize
        s, _ = self.utils.getStressAndTangent(self.volume() * 1.0, False)
        return [math.log(h0[0, 0] / h[0, 0]), math.log(h0[1, 1] / h[1, 1]), -s[0, 0], -s[1, 1],
                -0.5 * (s[0, 1] + s[1, 0]), self.utils.unbalancedForce(),
                self.O.interactions.countReal(), sliding_fraction(self.O)]

    def undrained_rate(self, rate):
        """The lateral compression rate that keeps the area constant to round-off under the axial
        one: the cell update h += dt L h multiplies it by (1 - r dt)(1 + r' dt) = 1."""
        return -rate / (1.0 - rate * self.dt)

    def servo_rate(self, sig, goal, stiff, rate_max):
        """Compression-positive strain rate moving sig towards goal."""
        if stiff <= 0:
            rate = rate_max
        else:
            rate = self.spec["gain"] * (goal - sig) / (stiff * self.spec["period"] * self.dt)
        return max(-rate_max, min(rate_max, rate))

    def set_rates(self, rates):
        """Compression-positive strain rates of the controlled axes (a diagonal velGrad)."""
        r = list(rates) + [0.0] * (3 - len(rates))
        self.O.cell.velGrad = self.Matrix3(-r[0], 0, 0, 0, -r[1], 0, 0, 0, -r[2])

    def state(self):
        return _state(self.O, self.utils, self.ids, self.spec["radii"])

    def consolidate(self):
        """Both directions servoed to p0 (and, with a target porosity, the friction lowered step
        by step); returns (status, message, record)."""
        O, utils, spec = self.O, self.utils, self.spec
        p0, period = spec["p0"], spec["period"]
        status, message = "ok", ""
        rate_c = spec["rate_compact"]
        target = spec.get("porosity")
        tan_phi = math.tan(spec["phi_compact"])
        reductions = 0
        done = 0
        next_check = 0
        sig = [0.0] * self.axes
        t_c, cpu_c = time.time(), time.process_time()
        while True:
            sig, stiff = self.normal()
            if done >= next_check:
                next_check += spec["check"]
                err = max(abs(s - p0) for s in sig) / p0
                unb = utils.unbalancedForce()
                if err <= spec["tol_stress"] and unb <= spec["tol_unbalanced"]:
                    n = self.porosity()
                    if target is None or n <= target:
                        if target is not None and reductions == 0:
                            status = "error"
                            message = (f"target porosity {target:g} is above the porosity "
                                       f"{n:.4g} of the sample compacted with friction "
                                       f"{math.degrees(spec['phi_compact']):g} deg, the loosest "
                                       f"this compaction gives: raise --compaction-friction")
                        break
                    if tan_phi == 0.0:
                        status = "error"
                        message = (f"target porosity {target:g} not reached: the frictionless "
                                   f"sample's porosity is {n:.4g}")
                        break
                    # target porosity: lower the friction and settle again
                    tan_phi = 0.9 * tan_phi if tan_phi > 0.01 else 0.0
                    utils.setContactFriction(math.atan(tan_phi))
                    reductions += 1
                if done >= spec["max_steps"]:
                    status = "no-equilibrium"
                    what = ("no contact yet" if O.interactions.countReal() == 0 else
                            f"stress error {err:.3g}, unbalanced force ratio {unb:.3g}")
                    message = (f"consolidation to p0 = {p0:g} not reached within {done} steps "
                               f"({what})")
                    break
            self.set_rates([self.servo_rate(s, p0, c, rate_c) for s, c in zip(sig, stiff)])
            steps(O, period)
            done += period
        self.set_rates([0.0] * self.axes)
        return status, message, {"steps": done, "wall_s": time.time() - t_c,
                                 "cpu_s": time.process_time() - cpu_c,
                                 "unbalanced": utils.unbalancedForce(), "stress": list(sig),
                                 "friction_deg": math.degrees(math.atan(tan_phi)),
                                 "friction_reductions": reductions}

    def shear(self):
        """The drained or undrained shear at the axial strain rate (axial extension when
        ``extension``); returns (rows, record)."""
        O, spec, dt = self.O, self.spec, self.dt
        p0, period, gain = spec["p0"], spec["period"], spec["gain"]
        self.utils.setContactFriction(spec["phi_g"])
        t_s, cpu_s = time.time(), time.process_time()
        rate = spec["strain_rate"]
        axial = -rate if spec.get("extension") else rate
        h0 = self.Matrix3(O.cell.hSize)
        n_rows, eps_end = spec["rows"], spec["axial_strain"]
        n_total = max(n_rows, int(round(eps_end / (rate * dt))))
        rows = [self.row(h0)]
        drained = spec["kind"] == "drained"
        rate_lat = spec["lateral_rate_factor"] * rate
        lateral = range(1, self.axes)
        integral = [0.0] * self.axes
        done = 0
        for k in range(1, n_rows + 1):
            end = int(round(k * n_total / n_rows))
            while done < end:
                rates = [axial] * self.axes
                if drained:  # each lateral stress servoed to p0 on its own
                    sig, stiff = self.normal()
                    for i in lateral:
                        u = (p0 - sig[i]) / (stiff[i] * period * dt) if stiff[i] > 0 else 0.0
                        integral[i] = max(-rate_lat, min(rate_lat, integral[i] + spec["gain_i"] * u))
                        rates[i] = max(-rate_lat, min(rate_lat, gain * u + integral[i]))
                else:
                    rates[1:] = [self.undrained_rate(axial)] * (self.axes - 1)
                self.set_rates(rates)
                n = min(period, end - done)
                steps(O, n)
                done += n
            rows.append(self.row(h0))
        self.set_rates([0.0] * self.axes)
        return rows, {"steps": done, "wall_s": time.time() - t_s, "cpu_s": time.process_time() - cpu_s,
                      "strain_rate": rate}


def run(spec, scene=_Test):
    """The answer to one request (see the module docstring); ``scene`` builds and controls it."""
    try:
        from yade import config
        version = str(config.version)
    except Exception:  # pragma: no cover - YADE without config.version
        version = "unknown"
    test = scene(spec)
    status, message, consolidation = test.consolidate()
    result = {"status": status, "message": message, "dt": test.dt, "yade_version": version,
              "consolidation": consolidation, "consolidated": test.state(), "rows": []}
    if status == "ok":
        rows, shear = test.shear()
        result.update(rows=rows, final=test.state(), shear=shear)
    return result
