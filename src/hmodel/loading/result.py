"""Tables of loading paths: one row per computed state, long format over material points."""

from __future__ import annotations

import csv
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..rev import RevState

#: Columns of every result table, in order (the output contract of docs/cli.md plus diagnostics).
COLUMNS = ("point", "stage", "step", "eps11", "eps22", "eps12", "sig11", "sig22", "sig12",
           "p", "q", "eps_v", "q_p", "frac_sliding", "frac_open", "frac_contact14",
           "frac_contact26")
#: Cell-diagnostic columns, fractions of the directions (see ``RevState.fractions``).
FRACTIONS = COLUMNS[-4:]
UNITS = {"sig11": "Pa", "sig22": "Pa", "sig12": "Pa", "p": "Pa", "q": "Pa"}


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
            names = COLUMNS + tuple(c for c in self.columns if c not in COLUMNS)  # then any tags
            w.writerow(names)
            cols = [self.columns[c] for c in names]
            for row in zip(*cols):
                w.writerow([v if isinstance(v, str) else repr(v.item()) for v in row])
        os.replace(tmp, path)


class Recorder:
    """Collects rows while a path runs; :meth:`result` builds the :class:`PathResult`."""

    def __init__(self, meta: dict | None = None,
                 columns: Callable[[RevState], dict[str, np.ndarray]] | None = None):
        self._rows: list[dict[str, np.ndarray]] = []
        #: more columns of the rows recorded from states (not from the compiled kernel's
        #: blocks, where they are NaN): e.g. ``Rev.solver_fractions``
        self.columns = columns
        self._step: np.ndarray | None = None
        self.meta = dict(meta or {})
        #: extra columns after :data:`COLUMNS`, with the value they take in the rows recorded
        #: from now on (a loading program's ``cycle``); set before the first row is recorded
        self.tags: dict[str, object] = {}

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
        """Append K consecutive states of B points: eps, sig (K, B, 3), frac (K, B, 4) in the
        order of :data:`FRACTIONS`, ``extra`` columns (K, B); only the points where ``mask``
        (B,) is true, and only the states that exist (a point dropped after a failure has NaN
        strains from then on)."""
        K, B = eps.shape[:2]
        if self._step is None:
            self._step = np.zeros(B, dtype=np.int64)
        m = np.ones(B, bool) if mask is None else np.asarray(mask, bool)
        valid = m[None, :] & np.isfinite(eps[..., 0])
        if K == 0 or not valid.any():
            return
        count = np.cumsum(valid, axis=0)
        steps = (self._step[None, :] + count)[valid]
        self._step += count[-1]
        pts = np.broadcast_to(np.arange(B), (K, B))[valid]
        eps, sig, frac = eps[valid], sig[valid], frac[valid]
        p, q = 0.5 * (sig[:, 0] + sig[:, 1]), sig[:, 0] - sig[:, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            q_p = np.where(p != 0, q / np.where(p != 0, p, 1.0), 0.0)
        row = {"point": pts, "stage": np.full(len(steps), stage, dtype=object),
               "step": steps, "eps11": eps[:, 0], "eps22": eps[:, 1], "eps12": eps[:, 2],
               "sig11": sig[:, 0], "sig22": sig[:, 1], "sig12": sig[:, 2],
               "p": p, "q": q, "eps_v": eps[:, 0] + eps[:, 1], "q_p": q_p}
        row.update({c: frac[:, j] for j, c in enumerate(FRACTIONS)})
        row.update({c: np.asarray(v, float)[valid] for c, v in (extra or {}).items()})
        row.update({c: np.full(len(steps), v) for c, v in self.tags.items()})
        self._rows.append(row)

    def result(self) -> PathResult:
        if not self._rows:
            cols = {c: np.array([]) for c in COLUMNS}
        else:
            names = COLUMNS + tuple(dict.fromkeys(c for r in self._rows for c in r if c not in COLUMNS))
            # a column some rows lack (one recorded from states only) is NaN there
            cols = {c: np.concatenate([r[c] if c in r else np.full(len(r["step"]), np.nan)
                                       for r in self._rows]) for c in names}
        order = np.lexsort((cols["step"], cols["point"])) if len(cols["step"]) else slice(None)
        return PathResult({c: v[order] for c, v in cols.items()}, self.meta)
