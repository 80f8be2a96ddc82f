"""The boundary-value problems: a plane-strain biaxial specimen and a strip footing.

Both start from a homogeneous isotropic state: every Gauss point consolidated to p0
(:func:`hmodel.loading.consolidate`) and the boundary loaded by p0 where it is not held by a
platen, wall or footing, so that the initial stress field is in equilibrium. Displacements are
measured from that state. There is no gravity (a weightless layer under the surcharge p0).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from skfem import FacetBasis, LinearForm, asm

from ..cell import CellSolver, ClosedFormSolver
from ..errors import InputError
from ..limits import check_count, check_memory
from ..params import Params, parse_point_assignments
from ..rev import Rev
from ..stability import second_order_work
from .assembly import volume_average
from .bands import shear_band
from .material import DaskStep, HModelMaterial
from .mesh import BBAR, Domain, dofs_where, gauss_points
from .newton import GlobalNewtonSettings, Problem, StepResult, run_steps
from .regularization import Regularization
from .result import FemResult, Snapshot

PLATENS = ("smooth", "rough")
#: Working memory of a Gauss point besides its cells (the basis, the assembled tangent, the
#: recorded fields) [bytes]; measured: about 3.6 kB (peak RSS of 8x16 and 64x128 Q4 runs).
FEM_BYTES_PER_GAUSS_POINT = 8192


def parse_imperfection(text: str, base: Params) -> tuple[Params, tuple[float, float, float]]:
    """``"alpha0=50,phi_g=28@X,Y,R"``: other parameters (angles in degrees) in the disc of
    radius R [m] around (X, Y) [m]."""
    spec, sep, where = str(text).partition("@")
    if not sep:
        raise InputError(f"--imperfection expects NAME=VALUE[,NAME=VALUE...]@X,Y,R, got {text!r}")
    items = [s.strip() for s in spec.split(",") if s.strip()]
    sets = parse_point_assignments(items, base)
    if len(sets) != 1 or not items:
        raise InputError(f"--imperfection takes one value per parameter, got {spec!r}")
    try:
        x, y, r = (float(v) for v in where.split(","))
    except ValueError:
        raise InputError(f"--imperfection zone expects X,Y,R in metres, got {where!r}") from None
    if not (np.isfinite(r) and r > 0):
        raise InputError(f"--imperfection radius must be positive, got {r}")
    return sets[0], (x, y, r)


def _zone_sets(domain: Domain, gx: np.ndarray, zone) -> np.ndarray:
    """Parameter set of each Gauss point: 1 inside the imperfection's disc, else 0."""
    if zone is None:
        return np.zeros(gx.shape[1], np.int64)
    x, y, r = zone
    if not domain.contains(x, y):
        raise InputError(f"imperfection centre ({x:g}, {y:g}) lies outside the "
                         f"{domain.width:g} x {domain.height:g} m domain")
    inside = (gx[0] - x) ** 2 + (gx[1] - y) ** 2 <= r * r
    if not inside.any():
        raise InputError(f"the imperfection disc of radius {r:g} m at ({x:g}, {y:g}) holds no "
                         "Gauss point: enlarge it or refine the mesh")
    return inside.astype(np.int64)


def _traction(basis, facets, p0: float) -> np.ndarray:
    """Nodal forces of the pressure p0 on ``facets`` (traction -p0 n, n the outer normal)."""
    fb = FacetBasis(basis.mesh, basis.elem, facets=facets, intorder=4)  # exact up to quadratic
    form = LinearForm(lambda v, w: -p0 * (w.n[0] * v[0] + w.n[1] * v[1]))
    return asm(form, fb)


class _Recorder:
    """Rows and snapshots of a run, filled after each converged step."""

    def __init__(self, pb: Problem, row, columns, save, eps0):
        self.pb, self.row, self.columns, self.save = pb, row, columns, save
        self.eps0 = eps0
        self.u = np.zeros(pb.basis.N)
        self.rows = {c: [] for c in columns}
        self.snapshots, self.residuals = [], []
        self.step = 0
        self._add(None, 0.0)

    def _add(self, step: StepResult | None, lam: float) -> None:
        mat = self.pb.material
        f_int = step.f_int if step is not None else None
        values = self.row(self.u, f_int, lam)
        values.update(step=self.step, newton_iterations=0 if step is None else step.iterations,
                      residual=0.0 if step is None else step.residuals[-1])
        for c in self.columns:
            self.rows[c].append(values[c])
        if self.save(self.step, lam):
            st = mat.state
            fr = st.fractions()
            if step is None:
                d2w = np.full(mat.n_points, np.nan)
            else:
                d2w = second_order_work(st.eps - self._prev[0], st.sig - self._prev[1])[1]
            self.snapshots.append(Snapshot(self.step, lam, self.u.copy(), st.eps - self.eps0, st.sig.copy(),
                                           fr["frac_sliding"], fr["frac_open"], d2w))

    def __call__(self, step: StepResult, lam: float) -> None:
        self.u = self.u + step.du[: self.u.size]  # a regularized problem has more unknowns
        self.step += 1
        self._add(step, lam)
        self.before()

    def before(self):
        st = self.pb.material.state
        self._prev = (st.eps.copy(), st.sig.copy())


def _material(params: Params, imperfection, domain, gx, solver, p0,
              scheduler: str | None = None) -> tuple[HModelMaterial, Rev, np.ndarray, tuple | None]:
    sets_params = [params]
    zone = None
    if imperfection is not None:
        weak, zone = parse_imperfection(imperfection, params) if isinstance(imperfection, str) else imperfection
        sets_params.append(weak)
    sets = _zone_sets(domain, gx, zone)
    rev = Rev(sets_params if len(sets_params) > 1 else params, solver)
    return HModelMaterial(rev, sets, p0, DaskStep(scheduler, rev) if scheduler else None), rev, sets, zone


def _problem(basis, material, fixed, g, f_ext, reg: Regularization, element: str) -> Problem:
    """The problem ``reg`` solves (:mod:`hmodel.fem.regularization`: the displacement problem,
    or the coupled one of the nonlocal model), with the B-bar strain for the elements that
    take it."""
    return reg.problem(basis, material, fixed, g, f_ext, element in BBAR)


def _check_common(p0: float, n_steps: int) -> None:
    if not (np.isfinite(p0) and p0 > 0):
        raise InputError(f"p0 must be a positive pressure, got {p0}")
    if not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
        raise InputError(f"the number of load steps must be a positive integer, got {n_steps!r}")
    check_count(n_steps, "load steps")


def _check_size(domain: Domain, params: Params, solver: CellSolver | None) -> None:
    """Refuse a mesh whose Gauss points' cells and finite-element arrays would not fit in the
    memory budget (:mod:`hmodel.limits`), before the mesh is built."""
    per_cell = (solver or ClosedFormSolver()).bytes_per_cell
    n = float(domain.n_gauss)
    check_memory(n * (float(params.n_theta) * per_cell + FEM_BYTES_PER_GAUSS_POINT),
                 f"a {domain.nx:.4g}x{domain.ny:.4g} {domain.element} mesh ({n:.4g} Gauss points × "
                 f"{params.n_theta:.4g} directions)")


def _reg_meta(reg: Regularization, domain: Domain) -> dict:
    warning = reg.warning(domain)
    return {"regularization": str(reg), "warnings": [warning] if warning else []}


def _save_rule(n_steps: int, n_saved: int):
    every = max(1, n_steps // max(1, n_saved))
    return lambda k, lam: k % every == 0 or lam >= 1.0 - 1e-12


def _run(name, domain, pb, columns, row, where, n_steps, n_saved, settings, progress, meta, eps0):
    # a cell solver converged to stress_rtol cannot balance forces more closely than that
    settings = replace(settings, rtol=max(settings.rtol, float(pb.material.rev.solver.stress_rtol)))
    rec = _Recorder(pb, row, columns, _save_rule(n_steps, n_saved), eps0)
    gx, dx = gauss_points(pb.basis)
    t0 = time.perf_counter()

    def on_step(step, lam):
        rec(step, lam)
        rec.residuals.append(step.residuals)
        if progress is not None:
            progress(lam)
    rec.before()
    try:
        out = run_steps(pb, n_steps, on_step, settings, where)
    finally:
        if isinstance(pb.material.step, DaskStep):
            pb.material.step.close()
    meta = {**meta, "rtol": settings.rtol, "seconds": time.perf_counter() - t0, "steps": out.n_steps,
            "gauss_points": int(dx.size), "dofs": int(pb.basis.N)}
    return FemResult(name, domain, tuple(columns), {k: np.asarray(v) for k, v in rec.rows.items()},
                     rec.snapshots, rec.residuals, gx, dx, meta, out.stopped)


BIAXIAL_COLUMNS = ("step", "eps11", "sig11", "sig22", "p", "q", "eps_v", "newton_iterations", "residual")


def biaxial(params: Params | None = None, p0: float = 2e5, axial_strain: float = 0.05, *,
            size: tuple[float, float] = (0.05, 0.1), mesh: tuple[int, int] = (8, 16),
            element: str = "q4", platens: str = "smooth", undrained: bool = False,
            imperfection: "str | tuple[Params, tuple[float, float, float]] | None" = None,
            n_steps: int = 100, solver: CellSolver | None = None,
            settings: GlobalNewtonSettings = GlobalNewtonSettings(), n_saved: int = 10,
            reference: bool = True, scheduler: str | None = None, progress=None,
            regularization: "str | Regularization | None" = None) -> FemResult:
    """Plane-strain biaxial test of a ``size`` = (width, height) [m] specimen.

    Consolidated to ``p0`` [Pa], then compressed by the top platen to ``axial_strain``
    (platen displacement / height) in ``n_steps`` load steps, the bottom platen fixed. Drained:
    the lateral sides carry the pressure p0 (a dead load). Undrained: the specimen's volume is
    held, not each point's: the lateral sides are smooth rigid walls that move apart by
    ``width * axial_strain * lambda``, so that the specimen's (linearized) volume is constant
    while water-free material points may dilate or contract locally (a constant-volume test;
    homogeneous, every point is isochoric as in ``hmodel run biaxial --undrained``).
    ``platens``: smooth (free lateral sliding; one node pinned) or rough (no lateral sliding).
    ``imperfection``: ``"NAME=VALUE,...@X,Y,R"`` (see :func:`parse_imperfection`).
    ``reference``: also run the material-point test of the same parameters (``result.reference``).
    ``scheduler``: a Dask scheduler's address; the Gauss points' material updates run there
    (:class:`~hmodel.fem.material.DaskStep`), with the same results.
    ``regularization``: ``"local"`` (default) or ``"nonlocal:ell=LENGTH"`` [m]
    (:mod:`hmodel.fem.regularization`); an ell below the element size is noted in
    ``meta["warnings"]``.
    """
    params = params or Params()
    _check_common(p0, n_steps)
    reg = Regularization.from_spec(regularization)
    if not (np.isfinite(axial_strain) and 0 < axial_strain < 1):
        raise InputError(f"axial strain must lie in (0, 1), got {axial_strain}")
    if platens not in PLATENS:
        raise InputError(f"platens must be smooth or rough, got {platens!r}")
    domain = Domain(*size, *mesh, element)
    reg.check(domain)
    _check_size(domain, params, solver)
    basis = domain.basis()
    gx, dx = gauss_points(basis)
    material, rev, sets, zone = _material(params, imperfection, domain, gx, solver, p0, scheduler)
    W, H = domain.width, domain.height
    tol = 1e-9 * max(W, H)
    bottom = dofs_where(basis, 1, lambda x: x[1] < tol)
    top_y = dofs_where(basis, 1, lambda x: x[1] > H - tol)
    left = dofs_where(basis, 0, lambda x: x[0] < tol)
    right = dofs_where(basis, 0, lambda x: x[0] > W - tol)
    g = np.zeros(basis.N)
    g[top_y] = -axial_strain * H
    fixed = [bottom, top_y]
    if platens == "rough":
        fixed += [dofs_where(basis, 0, lambda x: x[1] < tol), dofs_where(basis, 0, lambda x: x[1] > H - tol)]
    if undrained:
        g[right] = axial_strain * W  # walls after the platens: the wall wins at the corners
        fixed += [left, right]
        f_ext = np.zeros(basis.N)
    else:
        if platens == "smooth":  # no rigid-body translation in x: pin the bottom-left corner
            fixed.append(dofs_where(basis, 0, lambda x: (x[0] < tol) & (x[1] < tol)))
        sides = basis.mesh.facets_satisfying(lambda x: (x[0] < tol) | (x[0] > W - tol))
        f_ext = _traction(basis, sides, p0)
    pb = _problem(basis, material, np.unique(np.concatenate(fixed)), g, f_ext, reg, domain.element)
    eps0 = material.state.eps.copy()

    def row(u, f_int, lam):
        st = material.state
        if f_int is None:
            s11, s22 = volume_average(dx, st.sig[:, :2])
        else:  # mean boundary stresses from the platens' and sides' nodal forces
            s11 = (f_int[bottom].sum() - f_int[top_y].sum()) / (2 * W)
            s22 = (f_int[left].sum() - f_int[right].sum()) / (2 * H)
        de = st.eps - eps0
        return dict(eps11=lam * axial_strain, sig11=s11, sig22=s22, p=0.5 * (s11 + s22), q=s11 - s22,
                    eps_v=float(volume_average(dx, de[:, 0] + de[:, 1])))

    meta = {"test": "fem undrained biaxial" if undrained else "fem drained biaxial", "p0": p0,
            "axial_strain": axial_strain, "size": [W, H], "mesh": [domain.nx, domain.ny],
            "element": element, "platens": platens, "undrained": undrained, "n_steps": n_steps,
            "solver": rev.solver.name, "params": params.to_dict(),
            "imperfection": None if imperfection is None else str(imperfection),
            "imperfect_points": int(sets.sum()), **_reg_meta(reg, domain)}
    res = _run("biaxial", domain, pb, BIAXIAL_COLUMNS, row,
               lambda lam: f"axial strain {lam * axial_strain:.5g}", n_steps, n_saved, settings,
               progress, meta, eps0)
    if reference:
        from ..loading import run_biaxial
        res.reference = run_biaxial(params, p0, axial_strain, undrained=undrained, solver=rev.solver,
                                    step=axial_strain / n_steps)
    res.meta["band"] = shear_band(res, zone)
    return res


FOOTING_COLUMNS = ("step", "settlement", "s_B", "pressure", "newton_iterations", "residual")


def footing(params: Params | None = None, p0: float = 1e5, settlement: float = 0.05, *,
            width: float = 0.2, layer: tuple[float, float] = (1.0, 0.5), mesh: tuple[int, int] = (20, 10),
            element: str = "q4", rough: bool = True, n_steps: int = 50, solver: CellSolver | None = None,
            settings: GlobalNewtonSettings = GlobalNewtonSettings(), n_saved: int = 10,
            scheduler: str | None = None, progress=None,
            regularization: "str | Regularization | None" = None) -> FemResult:
    """Rigid strip footing of ``width`` [m] at the centre of the top of a ``layer`` = (width,
    depth) [m] layer, pushed down to ``settlement`` times its width in ``n_steps`` load steps.

    The layer is consolidated to p0 and the rest of its top carries the surcharge p0; its sides
    are smooth rigid walls, its base is fixed. ``rough``: the footing holds its nodes
    horizontally too. The footing's edges must fall on mesh nodes. Rows: the footing's mean
    contact pressure [Pa] (from the nodal forces under it) against its settlement [m].
    ``scheduler``, ``regularization``: as for :func:`biaxial`.
    """
    params = params or Params()
    _check_common(p0, n_steps)
    reg = Regularization.from_spec(regularization)
    if not (np.isfinite(settlement) and 0 < settlement < 1):
        raise InputError(f"settlement / width must lie in (0, 1), got {settlement}")
    domain = Domain(*layer, *mesh, element)
    reg.check(domain)
    _check_size(domain, params, solver)
    L, H = domain.width, domain.height
    if not (np.isfinite(width) and 0 < width < L):
        raise InputError(f"footing width must be positive and less than the layer's {L:g} m, got {width:g}")
    edges = np.array([L - width, L + width]) / 2 / (L / domain.nx)
    if not np.allclose(edges, np.round(edges), atol=1e-6):
        raise InputError(f"the footing's edges ({(L - width) / 2:g} and {(L + width) / 2:g} m) must fall on "
                         f"mesh nodes (element width {L / domain.nx:g} m): choose --mesh accordingly")
    basis = domain.basis()
    gx, dx = gauss_points(basis)
    material, rev, _, _ = _material(params, None, domain, gx, solver, p0, scheduler)
    tol = 1e-9 * max(L, H)
    under = lambda x: (x[1] > H - tol) & (np.abs(x[0] - L / 2) <= width / 2 + tol)  # noqa: E731
    foot_y = dofs_where(basis, 1, under)
    g = np.zeros(basis.N)
    g[foot_y] = -settlement * width
    fixed = [foot_y, dofs_where(basis, 0, lambda x: (x[0] < tol) | (x[0] > L - tol)),
             dofs_where(basis, 0, lambda x: x[1] < tol), dofs_where(basis, 1, lambda x: x[1] < tol)]
    if rough:
        fixed.append(dofs_where(basis, 0, under))
    surface = basis.mesh.facets_satisfying(
        lambda x: (x[1] > H - tol) & (np.abs(x[0] - L / 2) >= width / 2 - tol))
    f_ext = _traction(basis, surface, p0)
    pb = _problem(basis, material, np.unique(np.concatenate(fixed)), g, f_ext, reg, domain.element)

    def row(u, f_int, lam):
        pressure = p0 if f_int is None else -f_int[foot_y].sum() / width
        return dict(settlement=lam * settlement * width, s_B=lam * settlement, pressure=pressure)

    meta = {"test": "fem footing", "p0": p0, "settlement": settlement, "width": width,
            "layer": [L, H], "mesh": [domain.nx, domain.ny], "element": element, "rough": rough,
            "n_steps": n_steps, "solver": rev.solver.name, "params": params.to_dict(), **_reg_meta(reg, domain)}
    return _run("footing", domain, pb, FOOTING_COLUMNS, row,
                lambda lam: f"settlement {lam * settlement:.4g} B", n_steps, n_saved, settings,
                progress, meta, material.state.eps.copy())

