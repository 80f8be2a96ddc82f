"""The pieces every kind of dataset rows (:mod:`hmodel.data.kinds`) builds its rows from: the
states of paths at their start steps, the Dataset-2 increments from such states, and the Arrow
tables of H-cell and bi-hexagon rows (:mod:`hmodel.data.schema`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pyarrow as pa

from ..cell import CellState
from .schema import (
    EXTRA_COLUMNS,
    FLAG_COLUMNS,
    FLAG_COLUMNS_3D,
    STATE,
    STATE_B,
    arrow_schema,
    to_arrow,
)

#: Field order of the packed cell state (hmodel.cell.state.FIELDS) for each schema column.
PACKED = {"d1": 0, "d2": 1, "alpha": 2, "N1": 3, "N2": 4, "T1": 5, "l1": 6, "l2": 7}
#: The same for hexagon B's columns of a bi-hexagon state (hmodel.cell.bihex.BIHEX_FIELDS).
PACKED_B = {b: 8 + PACKED[a] for a, b in zip(STATE, STATE_B)}


def start_states(spec, first: np.ndarray, advance: Callable[[], np.ndarray]) -> np.ndarray:
    """The states (P, L, n_fields) of P paths at the spec's start steps: ``first`` (P, n_fields)
    at step 0, then what ``advance()`` returns at each step."""
    starts = spec.start_steps
    out = np.empty((first.shape[0], len(starts), first.shape[1]))
    level = 0
    if starts[0] == 0:
        out[:, 0] = first
        level = 1
    for k in range(1, spec.n_steps + 1):
        values = advance()
        if level < len(starts) and k == starts[level]:
            out[:, level] = values
            level += 1
    return out


def increment_rows(spec, params, solver, start: np.ndarray, l0, paths: np.ndarray,
                   alpha0: np.ndarray, theta: np.ndarray, strain: np.ndarray) -> pa.Table:
    """Rows of the spec's Dataset-2 increments (``n_increments`` directions, their magnitudes,
    ``substeps``) applied by ``solver`` to start states (P, L, n_fields): P cells of initial
    lengths ``l0`` = (l10, l20) (P,) each, at L states each, labelled by ``paths``, ``alpha0``,
    ``theta`` (P,) and ``strain`` (L,, the ``start_strain`` column). Used by the generator and
    by active learning (:mod:`hmodel.studies.refine`), whose start states are a REV's."""
    P, L, nf = start.shape
    J = spec.n_increments
    phi = spec.increment_angles
    deps = spec.increment_magnitudes[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=-1)  # (J, 2)
    l10 = np.broadcast_to(l0[0][:, None, None], (P, L, J))  # strains on the initial lengths
    l20 = np.broadcast_to(l0[1][:, None, None], (P, L, J))
    sub1 = -l10 * deps[:, 0] / spec.substeps
    sub2 = -l20 * deps[:, 1] / spec.substeps
    before = CellState(np.ascontiguousarray(np.broadcast_to(start[:, :, None, :], (P, L, J, nf))))
    state = before
    for _ in range(spec.substeps):
        state, f = solver.step(params, state, sub1, sub2)
    labels = (np.repeat(alpha0, L * J), np.repeat(paths, L * J), np.repeat(theta, L * J),
              np.tile(np.repeat(strain, J), P))
    return table(np.tile(deps, (P * L, 1)), before.values.reshape(-1, nf),
                 state.values.reshape(-1, nf), f.flags.reshape(-1, len(FLAG_COLUMNS)), labels)


def table(deps, before, after, flags, labels) -> pa.Table:
    """H-cell rows: strains (n, 2), states before and after (n, n_fields; a richer cell's fields
    beyond the 8 as :data:`~hmodel.data.schema.EXTRA_COLUMNS`), flags and the four labels."""
    cols = {"deps1": deps[:, 0], "deps2": deps[:, 1]}
    for c in STATE:
        cols[c] = before[:, PACKED[c]]
    for c in STATE:
        cols[f"{c}_next"] = after[:, PACKED[c]]
    for j, c in enumerate(FLAG_COLUMNS):
        cols[c] = flags[:, j]
    alpha0, paths, theta, start = labels
    cols.update(alpha0=alpha0, path_id=paths.astype(np.int32), theta=theta, start_strain=start)
    n_extra = before.shape[1] - 8
    schema = arrow_schema(n_extra=n_extra)
    if n_extra:
        cols.update(zip(EXTRA_COLUMNS, (before[:, 8:], after[:, 8:])))
    return pa.Table.from_arrays([to_arrow(cols[f.name], f.type) for f in schema], schema=schema)


def bihex_table(deps, before, after, flags, labels) -> pa.Table:
    """Bi-hexagon rows: strains (n, 3), states before and after (n, 16), the 11 flags and the
    four labels."""
    cols = {"deps1": deps[:, 0], "deps2": deps[:, 1], "deps3": deps[:, 2]}
    for packed in (PACKED, PACKED_B):
        for c, k in packed.items():
            cols[c] = before[:, k]
    for packed in (PACKED, PACKED_B):
        for c, k in packed.items():
            cols[f"{c}_next"] = after[:, k]
    for j, c in enumerate(FLAG_COLUMNS_3D):
        cols[c] = flags[:, j]
    cols.update(alpha0=labels[0], path_id=labels[1].astype(np.int32), theta=labels[2], start_strain=labels[3])
    schema = arrow_schema(dim=3)
    return pa.Table.from_arrays([to_arrow(cols[fl.name], fl.type) for fl in schema], schema=schema)
