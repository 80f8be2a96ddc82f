"""A REV's contacts one by one, and their fabric, measured as a DEM assembly's are
(docs/model3d.md, "Contact fabric").

A cell's meso-stress (report eq. 1.12) is the Love-Weber sum (eq. 1.11) over its contacts. This
module keeps the sum's terms apart: every contact of every cell of one material point, with its
branch direction in the global frame, its normal force and its f ⊗ l, each counting its cell's
weight w_c (eq. 1.17, or its 3D lift). Summed, (1/V) Σ w_c f ⊗ l is the REV's stress, which the
tests check against :meth:`hmodel.rev.Rev.stress` and :meth:`hmodel.rev.Rev3D.stress`. A DEM
sample's contacts (:func:`grain_contacts`) take the same form with weight 1, so that the model's
fabric and a granular assembly's are one measure (:func:`fabric`).

**A hexagon's contacts** (docs/model.md; state d1, d2, α, N1, N2, T1, lengths l1, l2; n its
axis, t its in-plane lateral axis; s_n, s_t = ±1 its mirror images):

- four inclined contacts (grains 1-2, 1-6, 4-3, 4-5), branch u = -s_n cos α n + s_t sin α t,
  length d1, tangential direction τ = -s_n sin α n - s_t cos α t: f ⊗ l = d1 (N1 u ⊗ u + T1 τ ⊗ u);
- two column contacts (2-3, 5-6) along n, N2 d2 n ⊗ n each;
- the extra contacts of Fig. 1.6 when over-compressed: grains 2-6 and 3-5 along t, F(2r - l2) l2
  t ⊗ t each, and grains 1-4 along n once per cell, F(2r - l1) l1 n ⊗ n (F linear or Hertz's law,
  as the cell's).

A 3D bi-hexagon (docs/model3d.md) is two such hexagons, A in the plane (n, t1) and B in (n, t2),
sharing grains 1 and 4, and with ``cross_contacts=frictionless`` the eight contacts between
them (:mod:`hmodel.cell.cross`): branch b = (δd2/2, ±l2/2, ±l3/2) in (n, t1, t2), F b ⊗ b / |b|.

**The fabric** of a set of contacts, those that carry (normal force > 0): the fabric tensor
F = Σ w u ⊗ u / Σ w (1/d of the identity when isotropic), its normal-force-weighted twin, and
the shares of the contacts, of the axial stress σ_aa and of the lateral stress σ_r (the mean of
the other normal components) carried by the contacts in each band of tilt from an axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..cell.base import STATE_BIHEXAGON, STATE_H_CELL
from ..cell.closed_form import hertz_constants
from ..cell.hertz import extra_force
from ..errors import InputError
from ..params import Params
from .rev import Rev
from .rev3d import Rev3D
from .state import RevState

#: Bands of tilt from the axis [deg] of :func:`fabric`, as the fabric note measured them.
TILT_BANDS = ((0.0, 30.0), (30.0, 50.0), (50.0, 70.0), (70.0, 90.0))
#: Mirror images (s_n, s_t) of a hexagon's inclined contacts, and of a bi-hexagon's cross pairs.
MIRRORS = ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0))


@dataclass(frozen=True)
class Contacts:
    """Contacts of one material point (K of them, d = 2 or 3 dimensions).

    Attributes
    ----------
    cell : ndarray (K,) int
        The cell (direction) each contact belongs to; -1 for a grain assembly's.
    branch : ndarray (K, d)
        Unit branch vector in the global frame.
    fn : ndarray (K,)
        Normal force [N], positive in compression.
    fl : ndarray (K, d, d)
        f ⊗ l [N m] of the contact (Love-Weber, eq. 1.11).
    weight : ndarray (K,)
        What the contact counts: its cell's weight (eq. 1.17), or 1 for a grain contact.
    """

    cell: np.ndarray
    branch: np.ndarray
    fn: np.ndarray
    fl: np.ndarray
    weight: np.ndarray

    def __len__(self) -> int:
        return len(self.fn)

    def carrying(self) -> "Contacts":
        """The contacts whose normal force is positive."""
        on = self.fn > 0.0
        return Contacts(self.cell[on], self.branch[on], self.fn[on], self.fl[on], self.weight[on])

    def stress(self, volume: float) -> np.ndarray:
        """σ (d, d) [Pa] = (1/V) Σ w f ⊗ l over the contacts, V the REV's (or sample's) volume."""
        return np.einsum("k,kij->ij", self.weight, self.fl) / volume


def _dyad(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, :, None] * b[:, None, :]


def _extra(params: Params):
    """F(gap) of the extra contacts, zero apart (vectorized :func:`hmodel.cell.hertz.extra_force`)."""
    c = hertz_constants(params)[0] if params.contact == "hertz-mindlin" else 0.0
    return np.vectorize(lambda gap: extra_force(params.kn, c, gap) if gap > 0.0 else 0.0, otypes=[float])


def hexagon_contacts(params: Params, v: np.ndarray, n: np.ndarray, t: np.ndarray, lt: np.ndarray):
    """The contacts of hexagons whose fields (d1, d2, α, N1, N2, T1) are ``v[:, :6]`` (C, ≥6), of
    axis ``n`` and in-plane lateral axis ``t`` (C, d), lateral length ``lt`` (C,): a list of
    (branch (C, d), fn (C,), f ⊗ l (C, d, d)), without grains 1-4's extra contact (one per cell).
    """
    d1, d2, a, n1, n2, t1 = (v[:, k] for k in range(6))
    ca, sa = np.cos(a)[:, None], np.sin(a)[:, None]
    out = []
    for sn, st in MIRRORS:
        u = -sn * ca * n + st * sa * t
        tau = -sn * sa * n - st * ca * t
        out.append((u, n1, d1[:, None, None] * (n1[:, None, None] * _dyad(u, u) + t1[:, None, None] * _dyad(tau, u))))
    column = (n2 * d2)[:, None, None] * _dyad(n, n)
    out += [(n, n2, column), (n, n2, column)]
    f = _extra(params)(2.0 * params.radius - lt)
    side = (f * lt)[:, None, None] * _dyad(t, t)
    return out + [(t, f, side), (t, f, side)]


def _cell_contacts(params: Params, v: np.ndarray, frames: np.ndarray, weights: np.ndarray) -> Contacts:
    """:func:`cell_contacts` of cells ``v`` (C, 8 or 16) of frames (C, d, d) (rows n, t[, t2])."""
    n = frames[:, 0, :]
    three_d = frames.shape[1] == 3
    pieces = hexagon_contacts(params, v, n, frames[:, 1, :], v[:, 7])
    if three_d:
        pieces += hexagon_contacts(params, v[:, 8:], n, frames[:, 2, :], v[:, 15])
    l1 = v[:, 6]
    f = _extra(params)(2.0 * params.radius - l1)
    pieces.append((n, f, (f * l1)[:, None, None] * _dyad(n, n)))
    if three_d and params.cross_contacts == "frictionless":
        dd2, l2, l3 = v[:, 1] - v[:, 9], v[:, 7], v[:, 15]
        for s2, s3 in MIRRORS:
            b = 0.5 * (dd2[:, None] * n + s2 * l2[:, None] * frames[:, 1, :] + s3 * l3[:, None] * frames[:, 2, :])
            dc = np.linalg.norm(b, axis=1)
            f = _extra(params)(2.0 * params.radius - dc)
            u = b / dc[:, None]
            pieces.append((u, f, (f * dc)[:, None, None] * _dyad(u, u)))
    index = np.arange(len(v))
    return Contacts(np.concatenate([index] * len(pieces)), np.concatenate([p[0] for p in pieces]),
                    np.concatenate([p[1] for p in pieces]), np.concatenate([p[2] for p in pieces]),
                    np.concatenate([weights] * len(pieces)))


def check_contacts(rev: Rev | Rev3D) -> None:
    """A one-line InputError where ``rev``'s cells have no contacts to list: cells whose state is
    not eq. 1.2's fields or whose stress is their own (DEM cells, meso surrogates)."""
    if isinstance(rev, Rev3D):
        ok = rev.solver.state_kind == STATE_BIHEXAGON
    else:
        ok = rev.solver.state_kind == STATE_H_CELL and not rev.own_meso
    if not ok:
        raise InputError(f"the contact fabric needs cells whose stress is eq. 1.12 of their contacts; "
                         f"{rev.solver.name!r} cells have their own state or meso-stress")


def cell_contacts(rev: Rev | Rev3D, state: RevState, point: int = 0) -> Contacts:
    """Every contact of material point ``point`` of ``state``, a state of ``rev`` (2D H-cells
    or 3D bi-hexagons whose stress is eq. 1.12 of their fields: the closed form, or a learned law
    of the H-cell's state; refused for cells with their own meso-stress, such as DEM cells).
    Each contact counts its cell's weight."""
    check_contacts(rev)
    if not 0 <= point < state.n_points:
        raise InputError(f"no material point {point} in a state of {state.n_points}")
    k = int(state.set_index[point])
    params = rev.sets[k]
    v = np.asarray(state.cells.values[point], float)
    if isinstance(rev, Rev3D):
        return _cell_contacts(params, v, rev.frames, rev.weights)
    c, s = np.cos(rev.directions.theta), np.sin(rev.directions.theta)
    frames = np.stack([np.stack([c, s], axis=1), np.stack([-s, c], axis=1)], axis=1)
    return _cell_contacts(params, v[:, :8], frames, rev.weights[k])


def grain_contacts(branch: np.ndarray, force: np.ndarray) -> Contacts:
    """Contacts of a grain assembly (a DEM sample): branch vectors l (K, d) from one grain's
    centre to the other's and the forces f (K, d) on the second by the first (compression:
    f along l); fn = f·l/|l|, each contact counting 1."""
    branch, force = np.asarray(branch, float), np.asarray(force, float)
    if branch.ndim != 2 or force.shape != branch.shape:
        raise InputError(f"grain contacts need branch vectors and forces of one shape (K, d), got "
                         f"{branch.shape} and {force.shape}")
    length = np.linalg.norm(branch, axis=1)
    if np.any(length <= 0.0):
        raise InputError("a grain contact's branch vector has zero length")
    u = branch / length[:, None]
    return Contacts(np.full(len(u), -1), u, np.einsum("ki,ki->k", force, u), _dyad(force, branch),
                    np.ones(len(u)))


@dataclass(frozen=True)
class Fabric:
    """The fabric of a set of carrying contacts (:func:`fabric`).

    Attributes
    ----------
    tensor, force_tensor : ndarray (d, d)
        Σ w u ⊗ u / Σ w, and Σ w fn u ⊗ u / Σ w fn.
    count : float
        Σ w over the carrying contacts (a REV's contacts per unit weight; a sample's number).
    stress_ratio : float
        σ_aa / σ_r of the contacts' stress.
    bands : list of dict
        Per band of tilt from the axis: ``lo``, ``hi`` [deg] and the shares ``contacts``,
        ``sig_axial``, ``sig_lateral`` of the band (NaN for a stress the contacts do not carry).
    """

    tensor: np.ndarray
    force_tensor: np.ndarray
    count: float
    stress_ratio: float
    bands: list

    def distance(self, other: "Fabric", share: str) -> float:
        """Total variation ½ Σ_bands |a - b| of one share (``contacts``, ``sig_axial``,
        ``sig_lateral``) between two fabrics of the same bands: 0 the same, 1 no band in common."""
        if [(b["lo"], b["hi"]) for b in self.bands] != [(b["lo"], b["hi"]) for b in other.bands]:
            raise InputError("fabrics of different bands cannot be compared")
        return 0.5 * sum(abs(a[share] - b[share]) for a, b in zip(self.bands, other.bands))

    @classmethod
    def from_dict(cls, d: dict) -> "Fabric":
        """The fabric of :meth:`as_dict`'s plain numbers."""
        return cls(np.array(d["tensor"]), np.array(d["force_tensor"]), d["count"], d["stress_ratio"], d["bands"])

    def as_dict(self) -> dict:
        """The fabric as plain numbers (a result's ``meta``, sample.json)."""
        return {"tensor": self.tensor.tolist(), "force_tensor": self.force_tensor.tolist(), "count": self.count,
                "stress_ratio": self.stress_ratio, "bands": [dict(b) for b in self.bands]}


def fabric_rows(fabrics: list[tuple[dict, dict]], axis: int = 0) -> list[dict]:
    """Rows of a contact-fabric table: for each (labels, :meth:`Fabric.as_dict`) pair, one row
    per tilt band: the labels, the band, its shares, and the fabric's axial components
    ``F_aa``, ``F_aa_force`` and ``stress_ratio`` (repeated on each of its rows)."""
    rows = []
    for labels, f in fabrics:
        for b in f["bands"]:
            rows.append({**labels, "tilt_lo": b["lo"], "tilt_hi": b["hi"], "contacts": b["contacts"],
                         "sig_axial": b["sig_axial"], "sig_lateral": b["sig_lateral"],
                         "F_aa": f["tensor"][axis][axis], "F_aa_force": f["force_tensor"][axis][axis],
                         "stress_ratio": f["stress_ratio"]})
    return rows


def fabric(contacts: Contacts, axis: int = 0, bands=TILT_BANDS) -> Fabric:
    """The fabric of ``contacts``' carrying ones relative to global axis ``axis`` (0: x1, the
    triaxial tests' compression axis): see :class:`Fabric`. Bands [deg] must cover 0-90 (the last
    includes 90°)."""
    if bands[0][0] != 0.0 or bands[-1][1] != 90.0 or any(a[1] != b[0] for a, b in zip(bands, bands[1:])):
        raise InputError(f"tilt bands must cover 0-90 degrees without gaps, got {list(bands)}")
    c = contacts.carrying()
    if len(c) == 0:
        raise InputError("no contact carries: the fabric of a force-free state is not defined")
    d = c.branch.shape[1]
    if not 0 <= axis < d:
        raise InputError(f"axis {axis} of a {d}D state")
    w = c.weight
    tensor = np.einsum("k,ki,kj->ij", w, c.branch, c.branch) / w.sum()
    force = np.einsum("k,ki,kj->ij", w * c.fn, c.branch, c.branch) / (w * c.fn).sum()
    others = [i for i in range(d) if i != axis]
    s_axial = w * c.fl[:, axis, axis]
    s_lateral = w * np.mean([c.fl[:, i, i] for i in others], axis=0)
    tilt = np.degrees(np.arccos(np.clip(np.abs(c.branch[:, axis]), 0.0, 1.0)))
    def share(x, on):  # NaN where the contacts carry none of it (all lateral: no axial stress)
        total = x.sum()
        return float(x[on].sum() / total) if total != 0.0 else math.nan

    rows = []
    for k, (lo, hi) in enumerate(bands):
        last = k == len(bands) - 1
        on = (tilt >= lo) & ((tilt <= hi) if last else (tilt < hi))
        rows.append({"lo": float(lo), "hi": float(hi), "contacts": share(w, on),
                     "sig_axial": share(s_axial, on), "sig_lateral": share(s_lateral, on)})
    ratio = float(s_axial.sum() / s_lateral.sum()) if s_lateral.sum() != 0.0 else math.inf
    return Fabric(tensor, force, float(w.sum()), ratio, rows)


def isotropic_shares(bands=TILT_BANDS, dim: int = 3) -> list[float]:
    """The share of each tilt band of an isotropic fabric: cos lo - cos hi on the sphere (3D),
    (hi - lo)/90° on the circle (2D)."""
    if dim == 3:
        return [math.cos(math.radians(lo)) - math.cos(math.radians(hi)) for lo, hi in bands]
    return [(hi - lo) / 90.0 for lo, hi in bands]
