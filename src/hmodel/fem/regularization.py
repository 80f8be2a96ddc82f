"""Regularized H-model: nonlocal inelastic stress averaged by an implicit-gradient operator.

The local model has no length: past the peak its shear band is one element wide and the
softening depends on the mesh (docs/fem.md). Here each Gauss point keeps its unchanged local
H-model (any cell solver, a black box), and only the part of its stress that departs from
elasticity is averaged over an internal length ``ell``:

    g = D_e : (eps - eps0) - (sig_loc(eps) - sig0)          inelastic stress of the point
    gbar - ell^2 lap(gbar) = g   in the body,  grad(gbar).n = 0 on its boundary
    sig = sig0 + D_e : (eps - eps0) - gbar                  stress in the equilibrium

(nonlocal inelastic stress after Bazant & Lin 1988 and the nonlocal microplane model of
Bazant & Ozbolt 1990; its average by the screened-Poisson (Helmholtz) equation, whose Green's
function is a kernel of width ell, after Peerlings, de Borst, Brekelmans & de Vree 1996, so that
the system stays sparse). eps0, sig0: the consolidated state; D_e: the points' elastic stiffness
there (the REV's tangent at the consolidated state, all contacts sticking). A homogeneous field
has gbar = g and sig = sig_loc: the regularized specimen still is the material point.

gbar (3 components, hmodel's order (11, 22, 12)) is a nodal field with the displacement's
interpolation. The global Newton solves for (u, gbar) together, with the consistent Jacobian

    [ K_e                          -int B^T W N  ] [du   ]     [ r_u ]
    [ -int N^T (D_e - D_t) B       M + ell^2 L   ] [dgbar]  = -[ r_g ]

(signs for hmodel's compression-positive strain eps = B u; W = diag(1, 1, 2) for the tensor
shear component; D_t the material's consistent tangent, which the FEM already has from finite
differences). Only the lower-left block changes between iterations. The Helmholtz rows are
divided by the element size, so that their residual is a force like the equilibrium's and one
norm measures both.

Everything here works on Gauss-point operators built once from scikit-fem's basis: B (3B x N,
:func:`hmodel.fem.assembly.strain_operator`) maps nodal displacements to the points' strains,
N (B x n) a nodal scalar to its point values.
The material is anything with the law interface of :mod:`hmodel.fem.material` (``trial``,
``commit``, ``checkpoint``, ``restore``, ``sig``), which the 1D verification uses with a
bilinear softening law.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import scipy.sparse as sp
from skfem import Basis

from ..errors import InputError
from .assembly import block_diagonal
from .material import Trial
from .newton import Problem

class Regularization:
    """How the Gauss points' stresses enter the equilibrium, and the problem that the global
    Newton solves for it: the base of the variants, each one class (:class:`Local`,
    :class:`Nonlocal`).

    A new variant is one subclass here, listed in :data:`VARIANTS`: its ``name`` (the word
    before the colon of ``--regularization``) and ``usage`` (its spec in the list of known
    ones), :meth:`from_options` (its options after the colon), ``__str__`` (its spec back),
    :meth:`problem` and, where it has them, :meth:`check` and :meth:`warning`.
    """

    #: the word that names the variant in a spec
    name: ClassVar[str]
    #: the variant's spec as the message of an unknown one lists it
    usage: ClassVar[str]

    @property
    def kind(self) -> str:
        """The variant's name (``local``, ``nonlocal``)."""
        return self.name

    @staticmethod
    def from_spec(spec) -> Regularization:
        """``None``/``"local"`` -> no regularization; ``"nonlocal:ell=0.005"`` (metres; also
        ``nonlocal:0.005``), ``"nonlocal:ell=0.005,m=0.2"`` -> :class:`Nonlocal`; a
        :class:`Regularization` passes through. One-line InputError for an unknown variant or
        bad options."""
        if spec is None:
            return Local()
        if isinstance(spec, Regularization):
            return spec
        name, _, opts = str(spec).strip().partition(":")
        name = name.strip().lower()
        for variant in VARIANTS:
            if variant.name == name:
                return variant.from_options(spec, opts)
        raise InputError(f"unknown regularization {spec!r} (known: {', '.join(v.usage for v in VARIANTS)})")

    @classmethod
    def from_options(cls, spec, opts: str) -> Regularization:
        """The variant of options ``opts`` (the spec ``spec`` after its colon, for messages)."""
        raise NotImplementedError(f"regularization {cls.name} does not say how its options are read")

    def problem(self, basis: Basis, material, fixed: np.ndarray, g: np.ndarray, f_ext: np.ndarray,
                b_bar: bool) -> Problem:
        """The :class:`~hmodel.fem.newton.Problem` of the displacement problem's arguments
        (``b_bar``: the B-bar strain of the elements that take it) under this regularization."""
        raise NotImplementedError(f"regularization {self.name} does not say what problem it solves")

    def check(self, domain) -> None:
        """Refuse (InputError) a regularization the :class:`~hmodel.fem.mesh.Domain` cannot
        take, before any work."""

    def warning(self, domain) -> str | None:
        """A warning about this regularization on the domain's mesh, or None."""
        return None


@dataclass(frozen=True)
class Local(Regularization):
    """No regularization: the local model, each Gauss point's own stress in the equilibrium."""

    name: ClassVar[str] = "local"
    usage: ClassVar[str] = "local"

    @classmethod
    def from_options(cls, spec, opts: str) -> Local:
        if opts.strip():
            raise InputError(f"the local model takes no options, got {spec!r}")
        return cls()

    def __str__(self) -> str:
        return "local"

    def problem(self, basis, material, fixed, g, f_ext, b_bar) -> Problem:
        return Problem(basis, material, fixed, g, f_ext, b_bar)


@dataclass(frozen=True)
class Nonlocal(Regularization):
    """The inelastic stress averaged over ``ell`` [m] (:class:`NonlocalProblem`); ``m``: the
    nonlocal share of the inelastic stress in the equilibrium (1: fully nonlocal)."""

    ell: float
    m: float = 1.0
    name: ClassVar[str] = "nonlocal"
    usage: ClassVar[str] = "nonlocal:ell=LENGTH"

    def __post_init__(self):
        if self.ell is None or not (np.isfinite(self.ell) and self.ell > 0):
            raise InputError(f"the nonlocal regularization needs a length ell > 0 [m], got {self.ell!r}")
        if not (np.isfinite(self.m) and 0 < self.m <= 1):
            raise InputError(f"the nonlocal share m must lie in (0, 1], got {self.m!r}")

    @classmethod
    def from_options(cls, spec, opts: str) -> Nonlocal:
        values = {}
        for i, item in enumerate(opts.split(",")):
            name, eq, value = item.partition("=")
            if not eq and i == 0:
                name, value = "ell", name
            name = name.strip().lower()
            if name not in ("ell", "m") or name in values:
                raise InputError(f"the nonlocal regularization takes ell=LENGTH [m][,m=SHARE], got {spec!r}")
            try:
                values[name] = float(value)
            except ValueError:
                raise InputError(f"the nonlocal regularization's {name} must be a number, got {value!r}") from None
        if "ell" not in values:
            raise InputError(f"the nonlocal regularization needs ell=LENGTH [m], got {spec!r}")
        return cls(values["ell"], values.get("m", 1.0))

    def __str__(self) -> str:
        return f"nonlocal:ell={self.ell:g}" + (f",m={self.m:g}" if self.m != 1 else "")

    def problem(self, basis, material, fixed, g, f_ext, b_bar) -> Problem:
        return NonlocalProblem(basis, material, fixed, g, f_ext, b_bar, ell=self.ell, m=self.m)

    def check(self, domain) -> None:
        """Refuse an ell longer than the domain's largest dimension: the average would spread
        every point's inelastic stress over the whole body (no band fits, the band a few ell
        wide or more, docs/fem.md), and ell^2 times the gradient term would swamp the mass term
        of the Helmholtz rows beyond double precision (ell = 1e9 m: the first step never
        converges)."""
        size = max(domain.width, domain.height)
        if not self.ell <= size:
            raise InputError(f"the nonlocal length ell = {self.ell:g} m exceeds the largest dimension of the "
                             f"{domain.width:g} x {domain.height:g} m domain ({size:g} m): take ell of a few "
                             "elements, a fraction of the specimen")

    def warning(self, domain) -> str | None:
        """Where ell is below the element size: the band, a few ell wide, is then not resolved
        by the mesh."""
        h = element_size(domain)
        if self.ell < h:
            return (f"the nonlocal length ell = {self.ell:g} m is below the element size {h:.3g} m: the band "
                    "is not resolved (refine the mesh or take a larger ell)")
        return None


#: The variants a spec names, by their ``name``.
VARIANTS: tuple[type[Regularization], ...] = (Local, Nonlocal)


def parse_regularization(spec) -> Regularization:
    """:meth:`Regularization.from_spec`."""
    return Regularization.from_spec(spec)


def element_size(domain) -> float:
    """Largest element edge of a :class:`~hmodel.fem.mesh.Domain`'s grid [m] (the resolution
    that ell is compared with)."""
    return max(domain.width / domain.nx, domain.height / domain.ny)


def check_length(reg: Regularization, domain) -> None:
    """:meth:`Regularization.check`: a nonlocal ell longer than the domain is refused."""
    reg.check(domain)


def unresolved(reg: Regularization, domain) -> str | None:
    """:meth:`Regularization.warning`: a warning where a nonlocal ell is below the element
    size, else None."""
    return reg.warning(domain)


def scalar_operators(basis: Basis) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """N, d/dx, d/dy (each B x n) of a scalar basis: nodal values to Gauss-point values."""
    nel, nqp = basis.nelems, basis.X.shape[-1]
    b = np.arange(nel * nqp)
    out = []
    for part in ("value", "dx", "dy"):
        rows, cols, vals = [], [], []
        for i, phi in enumerate(basis.basis):
            f = phi[0]
            v = np.asarray(f) if part == "value" else f.grad[0 if part == "dx" else 1]
            rows.append(b), cols.append(np.repeat(basis.element_dofs[i], nqp))
            vals.append(np.asarray(v).ravel())
        out.append(sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                 shape=(nel * nqp, basis.N)))
    return tuple(out)


@dataclass
class CoupledTrial:
    """A trial of the coupled problem: the material's own (local stress, consistent tangent,
    state) and the nodal field gbar (n, 3, total), with ``sig`` the stress that enters the
    equilibrium (B, 3)."""

    local: Trial
    gbar: np.ndarray
    sig: np.ndarray

    @property
    def state(self):
        return self.local.state

    @property
    def D(self):
        return self.local.D


@dataclass
class NonlocalProblem(Problem):
    """A :class:`~hmodel.fem.newton.Problem` whose unknowns are the nodal displacements and,
    after them, the nodal nonlocal inelastic stress gbar (node-major, 3 per node). ``D_e``
    (B, 3, 3): the points' elastic stiffness; None takes the material's tangent at its
    committed state (symmetrized), which for the H-model at the consolidated state is the
    stiffness with every contact sticking."""

    ell: float = 0.0
    m: float = 1.0
    D_e: np.ndarray | None = None
    scalar: Basis = field(init=False)

    def __post_init__(self):
        b = self.basis
        self.scalar = Basis(b.mesh, b.elem.elem, quadrature=b.quadrature)
        self.n_u, self.n_g = b.N, 3 * self.scalar.N
        super().__post_init__()
        pad = np.zeros(self.n_g)
        self.g = np.concatenate([self.g, pad])
        self.f_ext = np.concatenate([self.f_ext, pad])
        dx = b.dx.ravel()
        npts = dx.size
        self.B, self.BtW = self.ops.B, self.ops.BtW  # the displacement problem's own
        N, Nx, Ny = scalar_operators(self.scalar)
        I3 = sp.identity(3, format="csr")
        self.N3 = sp.kron(N, I3, format="csr")  # gbar (3 n) -> points (3 B), point-major
        self.dx3 = np.repeat(dx, 3)
        if self.D_e is None:
            D = self.material.trial(np.zeros((npts, 3))).D
            self.D_e = 0.5 * (D + np.swapaxes(D, 1, 2))
        self.K_e = (self.BtW @ block_diagonal(self.D_e) @ self.B).tocsr()
        A = N.T @ sp.diags(dx) @ N + self.ell ** 2 * (Nx.T @ sp.diags(dx) @ Nx + Ny.T @ sp.diags(dx) @ Ny)
        # Helmholtz rows [Pa m^2] to forces [Pa m]: divided by a typical element size
        self.row_scale = 1.0 / float(np.sqrt(dx.sum() / b.nelems))
        self.A3 = (sp.kron(A, I3, format="csr") * self.row_scale).tocsr()
        self.K_ug = -self.m * (self.BtW @ self.N3).tocsr()
        self.NtDx = (self.N3.T @ sp.diags(self.dx3)).tocsr() * self.row_scale
        self.eps = np.zeros((npts, 3))  # committed strain since the start
        self.sig0 = self.material.sig.copy()
        self.gbar = np.zeros((self.scalar.N, 3))  # committed nodal gbar
        self.sig = self.sig0  # committed stress of the equilibrium

    @property
    def n_dofs(self) -> int:
        return self.n_u + self.n_g

    def _split(self, x: np.ndarray):
        return x[: self.n_u], x[self.n_u:].reshape(-1, 3)

    def evaluate(self, dx: np.ndarray):
        du, dg = self._split(dx)
        deps = (self.B @ du).reshape(-1, 3)
        local = self.material.trial(deps)
        eps = self.eps + deps
        gbar = self.gbar + dg
        elastic = np.einsum("bij,bj->bi", self.D_e, eps)
        g = elastic - (local.sig - self.sig0)  # the points' inelastic stress
        gbar_pts = (self.N3 @ gbar.ravel()).reshape(-1, 3)
        sig = self.sig0 + elastic - self.m * gbar_pts
        if self.m != 1:
            sig -= (1 - self.m) * g
        f_int = self.BtW @ sig.ravel()
        r_g = self.A3 @ gbar.ravel() - self.NtDx @ g.ravel()
        trial = CoupledTrial(local, gbar, sig)
        f = np.concatenate([f_int, np.zeros(self.n_g)])
        return trial, f, np.concatenate([f_int - self.f_ext[: self.n_u], r_g])

    def tangent(self, trial: CoupledTrial):
        inelastic = block_diagonal(self.D_e - trial.D) @ self.B  # d g / d u
        K_uu = self.K_e if self.m == 1 else self.K_e - (1 - self.m) * (self.BtW @ inelastic)
        return sp.bmat([[K_uu, self.K_ug], [-(self.NtDx @ inelastic), self.A3]], format="csr")

    def commit(self, trial: CoupledTrial) -> None:
        self.material.commit(trial.local)
        self.eps = self.eps + trial.local.deps
        self.gbar = trial.gbar
        self.sig = trial.sig

    def checkpoint(self):
        return self.material.checkpoint(), self.eps, self.gbar, self.sig

    def restore(self, saved) -> None:
        state, self.eps, self.gbar, self.sig = saved
        self.material.restore(state)

    def reference_force(self) -> float:
        return float(np.linalg.norm(self.BtW @ self.sig.ravel()))
