"""Internal forces and tangent stiffness from Gauss-point stresses and tangents (scikit-fem).

Sign and axis conventions. The finite-element fields are the usual ones: displacement
u = (u_x, u_y), strain e = sym(grad u) and stress s, tension positive. hmodel's material
points (like the report, eqs. 1.1-1.21) use soil mechanics' signs, compression positive, and
tensor components (11, 22, 12) with axis 1 the axial direction. Axis 1 is the vertical y
(the loading direction of the biaxial test and of the footing), axis 2 the horizontal x, so

    eps_hm = (-e_yy, -e_xx, -e_xy),    s_yy = -sig_hm[0], s_xx = -sig_hm[1], s_xy = -sig_hm[2].

eps12 is the tensor component (half the engineering shear strain) in both. The two sign flips
cancel in the tangent: with D = d sig_hm / d eps_hm (B, 3, 3) in hmodel's order, the
finite-element tangent in the order (yy, xx, xy) is the same D. The cell directions theta are
measured from axis 1 (vertical), which matters only for an anisotropic fabric (beta_omega).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import Basis, BilinearForm, LinearForm, asm


def strain_hm(basis: Basis, u: np.ndarray) -> np.ndarray:
    """Strain of the displacement field ``u`` at every Gauss point (B, 3), hmodel's
    convention (compression positive, (11, 22, 12) = (-yy, -xx, -xy))."""
    g = basis.interpolate(u).grad  # (2, 2, nelems, nqp): g[i, j] = du_i/dx_j
    return -np.stack([g[1, 1].ravel(), g[0, 0].ravel(), 0.5 * (g[0, 1] + g[1, 0]).ravel()], axis=1)


def _fields(basis: Basis, arr: np.ndarray) -> np.ndarray:
    """A Gauss-point array (B,) as scikit-fem's (nelems, nqp) field."""
    return np.ascontiguousarray(arr).reshape(basis.nelems, -1)


@LinearForm
def _internal(v, w):
    # e(v) : s with s = -sig_hm mapped to (yy, xx, xy)
    return -(v.grad[1][1] * w.s11 + v.grad[0][0] * w.s22 + (v.grad[0][1] + v.grad[1][0]) * w.s12)


def internal_force(basis: Basis, sig_hm: np.ndarray) -> np.ndarray:
    """Nodal internal forces f = int B^T s dV (N,) of Gauss-point stresses (B, 3) [N per m of
    thickness, plane strain]."""
    return asm(_internal, basis, s11=_fields(basis, sig_hm[:, 0]), s22=_fields(basis, sig_hm[:, 1]),
               s12=_fields(basis, sig_hm[:, 2]))


@BilinearForm
def _tangent(u, v, w):
    a = (u.grad[1][1], u.grad[0][0], 0.5 * (u.grad[0][1] + u.grad[1][0]))
    b = (v.grad[1][1], v.grad[0][0], 0.5 * (v.grad[0][1] + v.grad[1][0]))
    D = w.D
    ds = [D[i][0] * a[0] + D[i][1] * a[1] + D[i][2] * a[2] for i in range(3)]
    return b[0] * ds[0] + b[1] * ds[1] + 2.0 * b[2] * ds[2]


def stiffness(basis: Basis, D: np.ndarray):
    """Tangent stiffness K = int B^T D B dV (sparse N x N) of Gauss-point tangents D (B, 3, 3)
    in hmodel's order; not symmetric when D is not (non-associated sliding)."""
    Dw = np.ascontiguousarray(np.moveaxis(D, 0, -1)).reshape(3, 3, basis.nelems, -1)
    return asm(_tangent, basis, D=Dw)


def volume_average(dx: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Volume average over the Gauss points (weights ``dx`` (B,)) of values (B, ...)."""
    return np.tensordot(dx, values, axes=(0, 0)) / dx.sum()


def strain_operator(basis: Basis) -> sp.csr_matrix:
    """B (3 B x N): the Gauss points' strains in hmodel's convention, point-major rows
    (3 b + c; c in (11, 22, 12) = (-yy, -xx, -xy)), of the nodal displacements of ``basis``
    (a vector basis; points element-major as :func:`hmodel.fem.mesh.gauss_points`)."""
    nel, nqp = basis.nelems, basis.X.shape[-1]
    b = np.arange(nel * nqp)
    rows, cols, vals = [], [], []
    for i, phi in enumerate(basis.basis):
        g = phi[0].grad  # (2, 2, nel, nqp): d phi_i,k / dx_j
        dofs = np.repeat(basis.element_dofs[i], nqp)
        for c, v in enumerate((-g[1, 1], -g[0, 0], -0.5 * (g[0, 1] + g[1, 0]))):
            rows.append(3 * b + c)
            cols.append(dofs)
            vals.append(np.asarray(v).ravel())
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(3 * nel * nqp, basis.N))


def bbar(B: sp.csr_matrix, basis: Basis) -> sp.csr_matrix:
    """The B-bar strain operator of B (Hughes 1980): each point's volumetric strain
    eps11 + eps22 replaced by its element's mean (weighted by the points' dx), the deviatoric
    part kept, so that eps = dev(B u) + mean_e(tr B u) I / 2 (2D trace: the H-model's strain is
    in-plane). A mean dilatancy per element instead of one per Gauss point relieves the
    bilinear quadrilateral's volumetric locking under nearly isochoric or dilatant plastic
    flow, which stiffens a shear band that crosses the elements obliquely."""
    nel, nqp = basis.nelems, basis.X.shape[-1]
    dx = basis.dx.reshape(nel, nqp)
    w = (dx / dx.sum(axis=1, keepdims=True)).ravel()
    b = np.arange(nel * nqp)
    same = np.repeat(b.reshape(nel, nqp), nqp, axis=0).ravel()  # each point's element mates
    mean = sp.csr_matrix((np.repeat(w.reshape(nel, nqp), nqp, axis=0).ravel(),
                          (np.repeat(b, nqp), same)), shape=(b.size, b.size))
    vol = (B[0::3] + B[1::3]).tocsr()
    # rows 3b and 3b + 1 (eps11, eps22) of each point b get half its dilatation's correction
    normal = sp.csr_matrix((np.ones(2 * b.size), (np.concatenate([3 * b, 3 * b + 1]), np.tile(b, 2))),
                           shape=(3 * b.size, b.size))
    return (B + normal @ (0.5 * (mean @ vol - vol))).tocsr()


def block_diagonal(D: np.ndarray) -> sp.bsr_matrix:
    """Block-diagonal (3 B x 3 B) of per-point 3 x 3 matrices D (B, 3, 3)."""
    n = len(D)
    return sp.bsr_matrix((np.ascontiguousarray(D), np.arange(n), np.arange(n + 1)), shape=(3 * n, 3 * n))


class Operators:
    """:func:`strain_hm`, :func:`internal_force` and :func:`stiffness` of one basis as sparse
    products with its strain operator B, built once (scikit-fem's assembler re-evaluates the
    forms' basis functions at every call, which a Newton iteration of many Gauss points then
    pays twice). The same integrals: f = B^T W dx sig and K = B^T W dx D B, W = diag(1, 1, 2)
    (the tensor shear component counts twice in e : s); the two sign flips of hmodel's
    convention cancel in both. ``b_bar``: the strain operator is :func:`bbar`'s."""

    def __init__(self, basis: Basis, b_bar: bool = False):
        self.B = bbar(strain_operator(basis), basis) if b_bar else strain_operator(basis)
        dx = basis.dx.ravel()
        w = np.tile([1.0, 1.0, 2.0], dx.size) * np.repeat(dx, 3)
        self.BtW = (self.B.T @ sp.diags(w)).tocsr()

    def strain(self, u: np.ndarray) -> np.ndarray:
        """:func:`strain_hm` (B, 3)."""
        return (self.B @ u).reshape(-1, 3)

    def internal_force(self, sig: np.ndarray) -> np.ndarray:
        """:func:`internal_force` (N,)."""
        return self.BtW @ np.ascontiguousarray(sig).ravel()

    def stiffness(self, D: np.ndarray) -> sp.csr_matrix:
        """:func:`stiffness` (sparse N x N)."""
        return (self.BtW @ block_diagonal(D) @ self.B).tocsr()
