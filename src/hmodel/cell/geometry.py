"""The state of a cell of grains (a mesostructure) and its Love-Weber meso-stress, without YADE.

The DEM cell solver (:class:`hmodel.dem.solver.DEMSolver`) runs these cells in YADE; the
surrogates of them (:mod:`hmodel.surrogate.formulations.meso`) need only their geometry: how many fields a
state has, the unloaded state, and the meso-stress of a state. Both build on
:class:`CellGeometry`, which lives with the cells so that neither needs the other.

State layouts (``CellState.values``, last axis):

- ``standard``: the closed form's 8 fields ``d1, d2, alpha, N1, N2, T1, l1, l2``
  (:data:`hmodel.cell.state.FIELDS`). The cell is rebuilt mirror-symmetric: grains 1, 4 at
  (-/+ l1/2, 0), grains 2, 3 / 6, 5 at (-/+ d2/2, +/- l2/2); the four type-1 contacts carry
  T1 (signs of :data:`~hmodel.cell.mesostructure.TYPE1_SIGN`), the others none (zero by
  symmetry). Its meso-stress is eq. 1.12 of the fields, as for the closed form.
- a richer cell with g grains: the same 8 fields (measured on the six hexagon grains, as
  :func:`~hmodel.dem.scene.hcell_state` does; l1, l2 drive the localization), then the grain
  centres ``x_1, t_1, ..., x_g, t_g`` [m] (cell frame), then the tangential force ``ft`` [N]
  of every grain pair (i < j, in the order of ``numpy.triu_indices(g, 1)``; 0 when open),
  i.e. ``8 + 2 g + g (g - 1) / 2`` fields (:meth:`CellGeometry.field_names`). Its meso-stress
  is the symmetric Love-Weber sum over the closed contacts (normal force kn x overlap,
  tangential ``ft``) with the meso-volume of :meth:`Mesostructure.volume`
  (:meth:`CellGeometry.meso`).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..params import Params
from .mesostructure import TYPE1, TYPE1_SIGN, TYPE2, Mesostructure, build, option_names
from .state import FIELDS, CellState


class CellGeometry:
    """State layout, unloaded states and Love-Weber meso-stress of cells of one mesostructure.

    Attributes
    ----------
    mesostructure : str
        Its name (:data:`~hmodel.cell.mesostructure.CONSTRUCTORS`).
    options : dict
        Its options (``ratio``).
    n_grains : int
    pairs : ndarray, shape (P, 2)
        Every grain pair i < j, the order of the pair columns of a state.
    n_fields : int
        Fields of a state (see the module docstring).
    """

    def __init__(self, mesostructure: str = "standard", options: dict | None = None):
        self.mesostructure, self.options = mesostructure, dict(options or {})
        self.n_grains = build(mesostructure, **self.options).n_grains
        self.standard = mesostructure == "standard"
        self.pairs = np.array(np.triu_indices(self.n_grains, 1)).T
        self.n_fields = 8 if self.standard else 8 + 2 * self.n_grains + len(self.pairs)

    @classmethod
    def from_spec(cls, spec: str) -> tuple["CellGeometry", dict[str, float]]:
        """The geometry of a DEM cell-solver spec ``dem:NAME:K=V,...`` (NAME ``standard`` when
        empty), and its other options (the DEM solver's numerics), in their order.

        >>> geometry, rest = CellGeometry.from_spec("dem:hexagon-center:ratio=0.5,tol=1e-7")
        >>> geometry.options, rest, geometry.n_fields
        ({'ratio': 0.5}, {'tol': 1e-07}, 43)
        """
        parts = spec.split(":")
        name = parts[1] if len(parts) > 1 and parts[1] else "standard"
        opts = {}
        for item in (parts[2].split(",") if len(parts) > 2 and parts[2] else []):
            key, _, value = item.partition("=")
            try:
                opts[key.strip()] = float(value)
            except ValueError:
                raise InputError(f"DEM solver option must be NAME=NUMBER, got {item!r}") from None
        own = option_names(name)
        return (cls(name, {k: v for k, v in opts.items() if k in own}),
                {k: v for k, v in opts.items() if k not in own})

    def field_names(self) -> tuple[str, ...]:
        """Names of the fields of ``CellState.values`` for these cells."""
        if self.standard:
            return FIELDS
        g = self.n_grains
        pos = tuple(f"{a}_{k + 1}" for k in range(g) for a in ("x", "t"))
        return FIELDS + pos + tuple(f"ft_{i + 1}_{j + 1}" for i, j in self.pairs)

    def cell(self, params: Params, alpha0: float) -> Mesostructure:
        """The unloaded cell of opening angle alpha0 for the grain radius of ``params``."""
        return build(self.mesostructure, params.radius, float(alpha0), **self.options)

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles alpha0 (shape of ``alpha0``)."""
        alpha0 = np.asarray(alpha0, float)
        flat = alpha0.reshape(-1)
        rows = {}
        out = np.empty((flat.size, self.n_fields))
        for k, a in enumerate(flat):
            if a not in rows:
                m = self.cell(params, a)
                rows[a] = self.pack(params, m.positions[None], np.zeros((1, len(self.pairs))))[0]
            out[k] = rows[a]
        return CellState(out.reshape(*alpha0.shape, self.n_fields))

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells of opening angle params.alpha0."""
        return self.initial_cells(params, np.full(shape, params.alpha0))

    def pack(self, params: Params, pos: np.ndarray, ft: np.ndarray) -> np.ndarray:
        """State rows (n, n_fields) from centres (n, g, 2) and pair forces (n, P)."""
        n = len(pos)
        out = np.empty((n, self.n_fields))
        b1 = np.stack([pos[:, j] - pos[:, i] for i, j in TYPE1], axis=1)
        out[:, 0] = np.hypot(b1[..., 0], b1[..., 1]).mean(axis=1)
        out[:, 1] = np.mean([np.hypot(*(pos[:, j] - pos[:, i]).T) for i, j in TYPE2], axis=0)
        out[:, 2] = np.arctan2(np.abs(b1[..., 1]), np.abs(b1[..., 0])).mean(axis=1)
        fn, closed = self.normal_forces(params, pos)
        col = self.pair_columns()
        t1 = [col[c] for c in TYPE1]
        t2 = [col[c] for c in TYPE2]
        out[:, 3] = fn[:, t1].mean(axis=1)
        out[:, 4] = fn[:, t2].mean(axis=1)
        out[:, 5] = (ft[:, t1] * np.array(TYPE1_SIGN)).mean(axis=1)
        out[:, 6] = pos[:, 3, 0] - pos[:, 0, 0]
        out[:, 7] = 0.5 * (pos[:, 1, 1] + pos[:, 2, 1] - pos[:, 4, 1] - pos[:, 5, 1])
        if not self.standard:
            out[:, 8:8 + 2 * self.n_grains] = pos.reshape(n, -1)
            out[:, 8 + 2 * self.n_grains:] = ft
        return out

    def pair_columns(self) -> dict[tuple[int, int], int]:
        """The column of every grain pair (i, j), i < j, among the pair forces."""
        return {tuple(int(k) for k in p): c for c, p in enumerate(self.pairs)}

    def radii(self, params: Params) -> np.ndarray:
        return self.cell(params, params.alpha0).radii

    def normal_forces(self, params: Params, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normal forces kn x overlap (n, P) and closed-contact mask of every pair."""
        r = self.radii(params)
        i, j = self.pairs.T
        b = pos[:, j] - pos[:, i]
        overlap = r[i] + r[j] - np.hypot(b[..., 0], b[..., 1])
        return params.kn * np.maximum(overlap, 0.0), overlap >= 0.0

    def unpack(self, params: Params, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (n, g, 2) and pair forces (n, P) of state rows (n, n_fields)."""
        n = len(values)
        if not self.standard:
            g = self.n_grains
            return values[:, 8:8 + 2 * g].reshape(n, g, 2), values[:, 8 + 2 * g:]
        d2, t1, l1, l2 = values[:, 1], values[:, 5], values[:, 6], values[:, 7]
        z = np.zeros(n)
        pos = np.stack([np.stack(p, axis=-1) for p in (
            (-l1 / 2, z), (-d2 / 2, l2 / 2), (d2 / 2, l2 / 2), (l1 / 2, z), (d2 / 2, -l2 / 2),
            (-d2 / 2, -l2 / 2))], axis=1)
        ft = np.zeros((n, len(self.pairs)))
        col = self.pair_columns()
        for c, s in zip(TYPE1, TYPE1_SIGN):
            ft[:, col[c]] = s * t1
        return pos, ft

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray] | None:
        """(V sigma_nn, V sigma_tt, V sigma_nt) (..., 3) [N m] and meso-volume (...) [m^2].

        None for the standard cell, whose stress is eq. 1.12 of its 8 fields (the REV then
        keeps its compiled path). Otherwise the symmetric Love-Weber sum over the closed
        contacts, compression positive, and the area of the driven grains' polygon.
        """
        if self.standard:
            return None
        values = np.asarray(state.values, float)
        shape = values.shape[:-1]
        vsig, vol = self.love_weber(params, values.reshape(-1, self.n_fields))
        return vsig.reshape(*shape, 3), vol.reshape(shape)

    def love_weber(self, params: Params, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(V sigma_nn, V sigma_tt, V sigma_nt) (n, 3) and meso-volume (n,) of state rows (n,
        n_fields), every layout (for the standard cell it equals eq. 1.12 of its fields)."""
        pos, ft = self.unpack(params, flat)
        fn, closed = self.normal_forces(params, pos)
        i, j = self.pairs.T
        b = pos[:, j] - pos[:, i]
        e = b / np.hypot(b[..., 0], b[..., 1])[..., None]
        tang = np.stack([e[..., 1], -e[..., 0]], axis=-1)
        f = (fn[..., None] * e + ft[..., None] * tang) * closed[..., None]
        vs = np.einsum("npa,npb->nab", f, b)
        vsig = np.stack([vs[:, 0, 0], vs[:, 1, 1], 0.5 * (vs[:, 0, 1] + vs[:, 1, 0])], axis=-1)
        return vsig, self.cell(params, params.alpha0).volume(pos)
