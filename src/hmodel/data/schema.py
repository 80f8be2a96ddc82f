"""The public schema of the H-cell databases (report §2.3): column names, types and units.

One row is one cell increment: the cell strain ``deps1, deps2`` applied to the state *before*
(``alpha, l1, l2, d1, d2, N1, N2, T1``) gives the state *after* (``*_next``) and its flags.
Cell strains are measured on the cell's initial lengths and are positive in compression:
δl1 = −l10·δε1, δl2 = −l20·δε2. Angles in radians, lengths in the unit of the grain radius,
forces in N (kn in N/m).

Columns beyond the report's: ``alpha0`` (the cell's initial opening angle), ``path_id`` (the
monotonic Dataset-1 path a row belongs to), ``theta`` (that path's loading direction in the
(ε1, ε2) plane) and ``start_strain`` (its total strain at the state before; 0 for Dataset-1
rows, whose state before is the initial state). In Dataset 3 (REV histories), ``path_id`` is
one cell of one REV loading path, ``theta`` that cell's direction in the REV and
``start_strain`` the REV's axial strain since consolidation.

Richer DEM cells (``solver = "dem:hexagon-center"`` etc.) have states beyond these 8 fields
(grain centres and contact tangential forces, :mod:`hmodel.dem.solver`). Their shards carry two
more columns, :data:`EXTRA_COLUMNS` ``state_extra`` and ``state_extra_next``: fixed-size lists
of float64, the state fields 9.. before and after the increment, whose names (units m, then N)
the manifest lists under ``extra_fields``. Every other column is unchanged; datasets of the
closed form and of ``dem:standard`` have no extra column.

Datasets that draw a material per path (for networks over a range of materials) carry
:data:`MATERIAL_COLUMNS` ``kt_kn`` and ``phi_g`` [rad] after the labels: each row's own kt/kn
and φg.

**3D rows** (``dim = 3``, :data:`COLUMNS_3D`): one row is one increment of a bi-hexagon
(docs/model3d.md), the cell strains ``deps1, deps2, deps3`` of its three lengths
(δl1 = −l10·δε1, δl2 = −l20·δε2, δl3 = −l30·δε3, l30 = l20) applied to hexagon A's state
(the 2D columns above, l2 its column length) and hexagon B's (:data:`STATE_B`: the same fields
with ``_b``, l3 its column length, l1_b = l1), giving both after (``*_next``) and the 11 flags
of the bi-hexagon (:data:`FLAG_COLUMNS_3D`: A's five, B's five ``*_b``, ``cross``). The labels
are the 2D ones (``theta``: the path's angle between the axial cell strain and the lateral ones).
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa

#: Version of this schema; readers refuse datasets written with another one.
SCHEMA_VERSION = 1

STATE = ("alpha", "l1", "l2", "d1", "d2", "N1", "N2", "T1")
STATE_NEXT = tuple(f"{c}_next" for c in STATE)
FLAG_COLUMNS = ("sliding", "open1", "open2", "contact14", "contact26")
STRAIN = ("deps1", "deps2")
LABELS = ("alpha0", "path_id", "theta", "start_strain")
COLUMNS = STRAIN + STATE + STATE_NEXT + FLAG_COLUMNS + LABELS
#: 3D (bi-hexagon) datasets: three cell strains, hexagon B's state, eleven flags.
STRAIN_3D = ("deps1", "deps2", "deps3")
STATE_B = ("alpha_b", "l1_b", "l3", "d1_b", "d2_b", "N1_b", "N2_b", "T1_b")
STATE_B_NEXT = tuple(f"{c}_next" for c in STATE_B)
FLAG_COLUMNS_3D = FLAG_COLUMNS + tuple(f"{c}_b" for c in FLAG_COLUMNS) + ("cross",)
COLUMNS_3D = STRAIN_3D + STATE + STATE_B + STATE_NEXT + STATE_B_NEXT + FLAG_COLUMNS_3D + LABELS
#: Extra state of richer cells (only when the cell state has more than 8 fields).
EXTRA_COLUMNS = ("state_extra", "state_extra_next")
#: The material of each row, in datasets that draw one per path (``kt_kn_range``,
#: ``phi_g_range`` of :class:`~hmodel.data.generator.DatasetSpec`): kt/kn and φg [rad].
MATERIAL_COLUMNS = ("kt_kn", "phi_g")

UNITS = {
    "deps1": "-", "deps2": "-", "alpha": "rad", "l1": "m", "l2": "m", "d1": "m", "d2": "m",
    "N1": "N", "N2": "N", "T1": "N", **{f"{c}_next": u for c, u in
                                       [("alpha", "rad"), ("l1", "m"), ("l2", "m"), ("d1", "m"),
                                        ("d2", "m"), ("N1", "N"), ("N2", "N"), ("T1", "N")]},
    **{c: "bool" for c in FLAG_COLUMNS}, "alpha0": "rad", "path_id": "-", "theta": "rad",
    "start_strain": "-", "kt_kn": "-", "phi_g": "rad",
}
UNITS_3D = {**UNITS, "deps3": "-",
            **{c: UNITS[base] for c, base in zip(STATE_B + STATE_B_NEXT, STATE + STATE_NEXT)},
            **{c: "bool" for c in FLAG_COLUMNS_3D}}


def columns_for(dim: int = 2) -> tuple[str, ...]:
    """The columns of a 2D (H-cell) or 3D (bi-hexagon) dataset's rows."""
    return COLUMNS_3D if dim == 3 else COLUMNS


def arrow_schema(metadata: dict[bytes, bytes] | None = None, n_extra: int = 0, dim: int = 2,
                 material: bool = False) -> pa.Schema:
    """The Arrow schema of every shard (float64 values, bool flags, int32 path ids), with the
    :data:`MATERIAL_COLUMNS` where ``material`` (a material drawn per path), the
    :data:`EXTRA_COLUMNS` (lists of ``n_extra`` float64) when ``n_extra`` > 0; ``dim = 3``: the
    bi-hexagon's :data:`COLUMNS_3D`."""
    fields = []
    for c in columns_for(dim) + (MATERIAL_COLUMNS if material else ()):
        if c in FLAG_COLUMNS_3D:
            t = pa.bool_()
        elif c == "path_id":
            t = pa.int32()
        else:
            t = pa.float64()
        fields.append(pa.field(c, t, nullable=False))
    if n_extra:
        fields += [pa.field(c, pa.list_(pa.float64(), n_extra), nullable=False) for c in EXTRA_COLUMNS]
    return pa.schema(fields, metadata=metadata)


def to_arrow(values: np.ndarray, kind: pa.DataType) -> pa.Array:
    """A column of values as Arrow; (rows, size) values for a fixed-size list column."""
    if pa.types.is_fixed_size_list(kind):
        return pa.FixedSizeListArray.from_arrays(pa.array(np.ascontiguousarray(values).reshape(-1)),
                                                 kind.list_size)
    return pa.array(np.ascontiguousarray(values), type=kind)


def column_array(table: pa.Table, column: str) -> np.ndarray:
    """A column of a shard or sample table as NumPy; a fixed-size list column as (rows, size)."""
    col = table.column(column)
    if pa.types.is_fixed_size_list(col.type):
        flat = col.combine_chunks().flatten().to_numpy()
        return flat.reshape(len(col), col.type.list_size)
    return col.to_numpy()
