"""Tables of loading paths: one row per computed state, long format over material points."""

from __future__ import annotations

import csv
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..limits import check_rows, max_rows
from ..rev import RevState
from ..rev.state import (
    deviatoric_stress,
    equivalent_stress,
    mean_stress,
    volumetric_strain,
)

#: Tensor components of a state's strain and stress, by their number n (2D: 3, 3D: 6).
COMPONENTS = {3: ("11", "22", "12"), 6: ("11", "22", "33", "23", "13", "12")}
#: Cell-diagnostic columns, fractions of the directions (see ``RevState.fractions``).
FRACTIONS = ("frac_sliding", "frac_open", "frac_contact14", "frac_contact26")


#: The components in the order of a result table: 3D tables list the shears 12, 13, 23.
TABLE_ORDER = {3: COMPONENTS[3], 6: ("11", "22", "33", "12", "13", "23")}


def columns_for(n: int) -> tuple[str, ...]:
    """Columns of a result table of states with n components, in order: the output contract
    of docs/cli.md, the stress invariants (3D: also sqrt(3 J2), the Lode angle and b), the
    diagnostics."""
    comps = TABLE_ORDER[n]
    extra = ("q_eq", "lode", "b") if n == 6 else ()
    return ("point", "stage", "step", *(f"eps{c}" for c in comps), *(f"sig{c}" for c in comps),
            "p", "q", "eps_v", "q_p", *extra, *FRACTIONS)


#: Columns of every 2D result table.
COLUMNS = columns_for(3)
UNITS = {**{f"sig{c}": "Pa" for c in COMPONENTS[6]}, "p": "Pa", "q": "Pa", "q_eq": "Pa", "lode": "deg"}


def stress_columns(eps: np.ndarray, sig: np.ndarray) -> dict[str, np.ndarray]:
    """The component and invariant columns of states eps, sig (K, n): components, p, q, eps_v,
    q/p (0 where p = 0), and in 3D sqrt(3 J2), the Lode angle [deg] and b of :func:`lode_b`."""
    comps = COMPONENTS[sig.shape[-1]]
    p, q = mean_stress(sig), deviatoric_stress(sig)
    with np.errstate(divide="ignore", invalid="ignore"):
        q_p = np.where(p != 0, q / np.where(p != 0, p, 1.0), 0.0)
    cols = {**{f"eps{c}": eps[:, j] for j, c in enumerate(comps)},
            **{f"sig{c}": sig[:, j] for j, c in enumerate(comps)},
            "p": p, "q": q, "eps_v": volumetric_strain(eps), "q_p": q_p}
    if sig.shape[-1] == 6:
        cols["q_eq"] = equivalent_stress(sig)
        cols["lode"], cols["b"] = lode_b(sig)
    return cols


def lode_b(sig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lode angle [deg] and b = (s2 - s3)/(s1 - s3) of 3D stresses (K, 6), from the principal
    stresses s1 >= s2 >= s3 (compression positive). The angle is measured from triaxial
    compression (0°: s2 = s3, b = 0) to triaxial extension (60°: s1 = s2, b = 1), i.e.
    tan θ = √3 b / (2 − b); NaN where the stress is isotropic or not finite."""
    T = np.empty((len(sig), 3, 3))
    for (i, j), k in zip(((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)), range(6)):
        T[:, i, j] = T[:, j, i] = sig[:, k]
    ok = np.all(np.isfinite(sig), axis=1)  # a dropped point's rows are NaN
    principal = np.full((len(sig), 3), np.nan)
    principal[ok] = np.linalg.eigvalsh(T[ok])
    s3, s2, s1 = principal.T
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.where(s1 - s3 > 1e-12 * np.maximum(np.abs(s1), 1.0), (s2 - s3) / (s1 - s3), np.nan)
    return np.degrees(np.arctan2(np.sqrt(3.0) * b, 2.0 - b)), b


@dataclass(frozen=True)
class PathResult:
    """Columns of a loading path (see :data:`COLUMNS`), each a 1-D array of equal length.

    ``point`` indexes the material point of a batch; ``meta`` describes the run
    (parameters, path, per-point labels such as ``p0``).
    """

    columns: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["step"])

    @property
    def n_points(self) -> int:
        return int(self.columns["point"].max()) + 1 if len(self) else 0

    def point(self, b: int) -> "PathResult":
        """Rows of material point ``b`` only."""
        m = self.columns["point"] == b
        return PathResult({k: v[m] for k, v in self.columns.items()}, self.meta)

    def stage(self, name: str) -> "PathResult":
        """Rows of one stage (e.g. ``consolidation``, ``shear``)."""
        m = self.columns["stage"] == name
        return PathResult({k: v[m] for k, v in self.columns.items()}, self.meta)

    def to_csv(self, path: "str | os.PathLike") -> None:
        """Write the table atomically (a temporary file renamed into place)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".part")
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            first = columns_for(6 if "eps33" in self.columns else 3)
            names = first + tuple(c for c in self.columns if c not in first)  # then any tags
            w.writerow(names)
            cols = [self.columns[c] for c in names]
            for row in zip(*cols):
                w.writerow([v if isinstance(v, str) else repr(v.item()) for v in row])
        os.replace(tmp, path)


class Recorder:
    """Collects rows while a path runs; :meth:`result` builds the :class:`PathResult`.

    The rows stay within :func:`~hmodel.limits.max_rows`: the rows known before a run are
    counted then, but not an isotropic consolidation's increments (known only as it runs),
    so a row past the limit is refused (:class:`~hmodel.limits.WorkTooLarge`) rather than
    recorded."""

    def __init__(self, meta: dict | None = None,
                 columns: Callable[[RevState], dict[str, np.ndarray]] | None = None):
        self._rows: list[dict[str, np.ndarray]] = []
        #: more columns of the rows recorded from states (not from the compiled kernel's
        #: blocks, where they are NaN): e.g. ``Rev.solver_fractions``
        self.columns = columns
        self._step: np.ndarray | None = None
        #: strain and stress components of the states recorded (3 until one says otherwise)
        self.n_components = 3
        self.meta = dict(meta or {})
        #: extra columns after :data:`COLUMNS`, with the value they take in the rows recorded
        #: from now on (a loading program's ``cycle``); set before the first row is recorded
        self.tags: dict[str, object] = {}
        self._rows_limit = max_rows()
        self._n_rows = 0

    def record(self, state: RevState, stage: str, mask: np.ndarray | None = None) -> None:
        """Append one row per material point (only those where ``mask`` is true)."""
        B = state.n_points
        m = np.ones(B, bool) if mask is None else np.asarray(mask, bool)
        fr = state.fractions()
        frac = np.stack([fr[c] for c in FRACTIONS], axis=1)
        extra = {} if self.columns is None else {c: v[None] for c, v in self.columns(state).items()}
        self.record_block(state.eps[None], state.sig[None], frac[None], stage, m, extra)

    def record_block(self, eps: np.ndarray, sig: np.ndarray, frac: np.ndarray, stage: str,
                     mask: np.ndarray | None = None, extra: dict | None = None) -> None:
        """Append K consecutive states of B points: eps, sig (K, B, n), frac (K, B, 4) in the
        order of :data:`FRACTIONS`, ``extra`` columns (K, B); only the points where ``mask``
        (B,) is true, and only the states that exist (a point dropped after a failure has NaN
        strains from then on)."""
        K, B = eps.shape[:2]
        self.n_components = eps.shape[-1]
        if self._step is None:
            self._step = np.zeros(B, dtype=np.int64)
        m = np.ones(B, bool) if mask is None else np.asarray(mask, bool)
        valid = m[None, :] & np.isfinite(eps[..., 0])
        if K == 0 or not valid.any():
            return
        self._n_rows += int(valid.sum())
        if self._n_rows > self._rows_limit:
            check_rows(self._n_rows, "the rows recorded so far (a consolidation's increments are "
                                     "known only as it runs)")
        count = np.cumsum(valid, axis=0)
        steps = (self._step[None, :] + count)[valid]
        self._step += count[-1]
        pts = np.broadcast_to(np.arange(B), (K, B))[valid]
        eps, sig, frac = eps[valid], sig[valid], frac[valid]
        row = {"point": pts, "stage": np.full(len(steps), stage, dtype=object), "step": steps,
               **stress_columns(eps, sig)}
        row.update({c: frac[:, j] for j, c in enumerate(FRACTIONS)})
        row.update({c: np.asarray(v, float)[valid] for c, v in (extra or {}).items()})
        row.update({c: np.full(len(steps), v) for c, v in self.tags.items()})
        self._rows.append(row)

    def result(self) -> PathResult:
        first = columns_for(self.n_components)
        if not self._rows:
            cols = {c: np.array([]) for c in first}
        else:
            names = first + tuple(dict.fromkeys(c for r in self._rows for c in r if c not in first))
            # a column some rows lack (one recorded from states only) is NaN there
            cols = {c: np.concatenate([r[c] if c in r else np.full(len(r["step"]), np.nan)
                                       for r in self._rows]) for c in names}
        order = np.lexsort((cols["step"], cols["point"])) if len(cols["step"]) else slice(None)
        return PathResult({c: v[order] for c, v in cols.items()}, self.meta)
