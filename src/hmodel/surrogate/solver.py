"""The ANN-based H-cell: a trained surrogate behind the cell-solver interface (report ch. 3).

``SurrogateSolver.step(params, state, dl1, dl2)`` replaces eq. 1.7 in the REV: every cell of
every material point is evaluated in one batched NumPy call. Cell length increments are turned
into the database's cell strains (δε = −δl / l0, on the initial lengths); an increment larger
than the ones the network was trained on is split into equal sub-steps. The network's answer
for a zero increment is subtracted from its answer (see :meth:`SurrogateSolver._predict`). The network predicts
α′, N1′, N2′, T1′; the lengths follow the strain, and d1, d2 follow from α′ and the lengths by
eq. 1.2 (d1 = l2 / (2 sin α), d2 = l1 − 2 d1 cos α), so the state stays geometrically
consistent.

Cells whose inputs lie outside the training domain are either handed to the closed-form
solver (``on_outside="fallback"``) or stop the run (``"error"``); ``counts`` reports how many.
"""

from __future__ import annotations

import math

import numpy as np

from ..cell import CellFlags, CellState
from ..cell.closed_form import ClosedFormSolver
from ..errors import InputError, SolverError
from ..params import Params
from .model import Surrogate

#: Parameters a surrogate is specific to (it was trained on cells with these values).
MATERIAL = ("kn", "kt_kn", "phi_g", "radius", "g2", "sliding_rhs", "volume")


class SurrogateSolver:
    """Implements :class:`hmodel.cell.CellSolver` with a trained :class:`Surrogate`."""

    name = "surrogate"

    def __init__(self, model: Surrogate, on_outside: str = "fallback", margin: float = 0.0,
                 opening: str = "rule"):
        if on_outside not in ("fallback", "error"):
            raise InputError(f"on_outside must be fallback or error, got {on_outside!r}")
        if opening not in ("rule", "classifier"):
            raise InputError(f"opening must be rule or classifier, got {opening!r}")
        self.model, self.on_outside, self.margin, self.opening = model, on_outside, margin, opening
        self.closed_form = ClosedFormSolver()
        self.counts = {"cell_updates": 0, "outside": 0, "substeps": 0}
        r = model.input_range
        # Largest trained strain increment: the bound of the deps1, deps2 inputs.
        self.max_increment = float(np.abs(r[:, :2]).max()) if r is not None else math.inf

    def check(self, params: Params) -> None:
        """Refuse a material the surrogate was not trained for."""
        trained = self.model.meta.get("params")
        if not trained:
            return
        mine = params.to_dict()
        wrong = [k for k in MATERIAL if k in trained and not _same(trained[k], mine[k])]
        if wrong:
            raise InputError("the surrogate was trained for other material parameters: " + ", ".join(
                f"{k}={trained[k]} (run: {mine[k]})" for k in wrong))

    def step(self, params: Params, state: CellState, dl1, dl2) -> tuple[CellState, CellFlags]:
        self.check(params)
        shape = state.shape
        v = state.values.reshape(-1, 8)
        d1 = np.broadcast_to(dl1, shape).reshape(-1)
        d2 = np.broadcast_to(dl2, shape).reshape(-1)
        l10, l20 = params.l10, params.l20
        e1, e2 = -d1 / l10, -d2 / l20
        n_sub = max(1, math.ceil(max(np.abs(e1).max(initial=0.0), np.abs(e2).max(initial=0.0))
                                 / self.max_increment - 1e-12))
        values, flags = v, None
        for _ in range(n_sub):
            values, flags = self._one(params, values, e1 / n_sub, e2 / n_sub, d1 / n_sub, d2 / n_sub)
        self.counts["substeps"] += n_sub
        return CellState(values.reshape(*shape, 8)), CellFlags(flags.reshape(*shape, 5))

    def _one(self, params, v, e1, e2, dl1, dl2):
        cols = {"deps1": e1, "deps2": e2, "d1": v[:, 0], "d2": v[:, 1], "alpha": v[:, 2],
                "N1": v[:, 3], "N2": v[:, 4], "T1": v[:, 5], "l1": v[:, 6], "l2": v[:, 7]}
        X = self.model.formulation.inputs(cols)
        out_mask = self.model.outside(X, self.margin)
        n_out = int(out_mask.sum())
        self.counts["cell_updates"] += len(v)
        self.counts["outside"] += n_out
        if n_out and self.on_outside == "error":
            i = int(np.flatnonzero(out_mask)[0])
            raise SolverError(f"{n_out} cell(s) outside the surrogate's training domain, e.g. "
                              + ", ".join(f"{k}={cols[k][i]:.4g}" for k in ("deps1", "deps2", "alpha", "l1", "l2", "N1", "N2", "T1")))
        pred = self._predict(cols, X)
        a = pred["alpha_next"]
        l1, l2 = v[:, 6] + dl1, v[:, 7] + dl2
        b1 = l2 / (2.0 * np.sin(a))  # eq. 1.2
        b2 = l1 - 2.0 * b1 * np.cos(a)
        new = np.column_stack([b1, b2, a, pred["N1_next"], pred["N2_next"], pred["T1_next"], l1, l2])
        two_r = 2.0 * params.radius
        opened = (pred["N1_next"] == 0) & (pred["N2_next"] == 0)
        if self.opening == "rule":  # separated grains carry no force (DESIGN.md step 3)
            opened |= (b1 > two_r) | (b2 > two_r)
            for k in (3, 4, 5):
                new[opened, k] = 0.0
        flags = np.column_stack([
            (np.abs(pred["T1_next"]) >= params.tan_phi * pred["N1_next"] * (1 - 1e-9)) & ~opened,
            opened, opened, l1 <= two_r, l2 <= two_r])
        if n_out:
            cf, cflags = self.closed_form.step(params, CellState(v[out_mask]), dl1[out_mask], dl2[out_mask])
            new[out_mask], flags[out_mask] = cf.values, cflags.flags
        if not np.all(np.isfinite(new)):
            raise SolverError("the surrogate returned a non-finite cell state")
        return new, flags


    def _predict(self, cols, X):
        """Network prediction with the zero-increment correction: the network's answer for a
        zero strain increment is subtracted, so that a cell without strain keeps its state and
        the network's bias does not accumulate over the thousands of increments of a path."""
        f, m = self.model.formulation, self.model
        X0 = X.copy()
        X0[:, :2] = 0.0
        Y, Y0 = m.forward(X), m.forward(X0)
        if f.name == "report":
            before = np.column_stack([cols[k] for k in ("alpha", "N1", "N2", "T1")])
            return f.decode(cols, before + Y - Y0)
        s_in = f.mobilized_friction(cols["N1"], cols["T1"])
        Y = Y.copy()
        Y[:, :3] -= Y0[:, :3]
        Y[:, 3] = s_in + Y[:, 3] - Y0[:, 3]
        if self.opening == "rule":
            # Opening decided as eq. 1.7's closed form does, on the continued force increments
            # (regressed on closed cells only): a force that would turn negative opens the cell.
            trial1, trial2 = cols["N1"] + f.force_scale * Y[:, 1], cols["N2"] + f.force_scale * Y[:, 2]
            Y[:, 4] = np.where((trial1 < 0) | (trial2 < 0), 1.0, -1.0)
        return f.decode(cols, Y)


def _same(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def load_solver(spec: str, on_outside: str = "fallback") -> SurrogateSolver:
    """``surrogate`` (the shipped model) or ``surrogate:PATH``."""
    from .modelfile import load
    from .shipped import shipped_path

    _, _, path = spec.partition(":")
    return SurrogateSolver(load(path or shipped_path()), on_outside)
