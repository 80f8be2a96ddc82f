"""Cleaning rules of the databases (report §2.3, Fig. 2.2): named, optional row filters.

Datasets are stored raw; a rule marks the rows it would remove, and readers apply the rules
they are given. Each rule is a function of a row's columns and the grain radius r.

| rule | removes rows where | why |
|---|---|---|
| ``short`` (the report's) | l1_next < 2r or l2_next < 2r | grains 1-4 or the columns 2-3/5-6 interpenetrate: the cell left the H geometry |
| ``short-input`` | l1 < 2r or l2 < 2r | the state before is already outside the H geometry |
| ``broken`` | open1 or open2 | a contact opened: the cell carries no force (trivial targets) |
| ``unloaded-input`` | N1 = N2 = 0 after some loading | the state before is a broken, force-free cell |
| ``non-finite`` | any value NaN or infinite | never expected; guards the training sets |
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .schema import COLUMNS, FLAG_COLUMNS


@dataclass(frozen=True)
class Rule:
    """A cleaning rule: the columns it reads, the rows it removes, and why (one line)."""

    columns: tuple[str, ...]
    removes: Callable[[dict[str, np.ndarray], float], np.ndarray]
    description: str


_FLOATS = tuple(c for c in COLUMNS if c not in FLAG_COLUMNS and c != "path_id")

RULES: dict[str, Rule] = {
    "short": Rule(("l1_next", "l2_next"),
                  lambda c, r: (c["l1_next"] < 2 * r) | (c["l2_next"] < 2 * r),
                  "l1 or l2 below 2r after the increment (the report's rule)"),
    "short-input": Rule(("l1", "l2"), lambda c, r: (c["l1"] < 2 * r) | (c["l2"] < 2 * r),
                        "l1 or l2 below 2r before the increment"),
    "broken": Rule(("open1", "open2"), lambda c, r: c["open1"] | c["open2"],
                   "a contact open after the increment (force-free cell)"),
    "unloaded-input": Rule(("N1", "N2", "start_strain"),
                           lambda c, r: (c["N1"] == 0) & (c["N2"] == 0) & (c["start_strain"] > 0),
                           "force-free (broken) cell before the increment"),
    "non-finite": Rule(_FLOATS,
                       lambda c, r: ~np.all(np.isfinite(np.stack([c[k] for k in _FLOATS])), axis=0),
                       "a NaN or infinite value"),
}

#: Rules applied unless others are asked for: the report's, and the guard against NaN.
DEFAULT_RULES = ("short", "non-finite")


def parse_rules(text: "str | Sequence[str] | None") -> tuple[str, ...]:
    """``"short,broken"`` or a sequence -> validated rule names; ``"none"`` -> ()."""
    if text is None:
        return DEFAULT_RULES
    names = [t.strip() for t in (text.split(",") if isinstance(text, str) else text) if t.strip()]
    if names == ["none"]:
        return ()
    unknown = [n for n in names if n not in RULES]
    if unknown:
        raise InputError(f"unknown cleaning rule(s) {', '.join(unknown)} "
                         f"(known: {', '.join(RULES)}, or none)")
    return tuple(dict.fromkeys(names))


def rule_columns(rules: Sequence[str]) -> list[str]:
    cols: dict[str, None] = {}
    for name in rules:
        cols.update(dict.fromkeys(RULES[name].columns))
    return list(cols)


def rule_masks(columns: dict[str, np.ndarray], rules: Sequence[str], radius: float) -> dict[str, np.ndarray]:
    """Boolean mask of the rows each rule removes."""
    return {name: np.asarray(RULES[name].removes(columns, radius), bool) for name in rules}


def keep_mask(columns: dict[str, np.ndarray], rules: Sequence[str], radius: float) -> np.ndarray:
    """Rows that no rule removes."""
    n = len(next(iter(columns.values()))) if columns else 0
    keep = np.ones(n, bool)
    for m in rule_masks(columns, rules, radius).values():
        keep &= ~m
    return keep


def _radius(ds) -> float:
    return float(ds.manifest["params"]["radius"])


def rule_counts(ds, rules: Sequence[str], progress: Callable[[float], None] | None = None) -> dict[str, int]:
    """Rows each rule removes on its own, plus ``total`` removed by any, over a whole dataset."""
    counts = dict.fromkeys(rules, 0)
    counts["total"] = 0
    cols = rule_columns(rules)
    if not cols:
        return counts
    n = len(ds.shards())
    for i, t in enumerate(ds.iter_tables(cols)):
        c = {k: t.column(k).to_numpy() for k in cols}
        masks = rule_masks(c, rules, _radius(ds))
        for name, m in masks.items():
            counts[name] += int(m.sum())
        counts["total"] += int(np.any(np.stack(list(masks.values())), axis=0).sum())
        if progress is not None:
            progress((i + 1) / n)
    return counts


def kept_rows(ds, rules: Sequence[str], progress: Callable[[float], None] | None = None) -> np.ndarray:
    """Global indices (sorted) of the rows that no rule removes, streamed shard by shard."""
    cols = rule_columns(rules)
    if not cols:
        return np.arange(ds.n_rows)
    out, offset, n = [], 0, len(ds.shards())
    for i, t in enumerate(ds.iter_tables(cols)):
        c = {k: t.column(k).to_numpy() for k in cols}
        out.append(offset + np.flatnonzero(keep_mask(c, rules, _radius(ds))))
        offset += t.num_rows
        if progress is not None:
            progress((i + 1) / n)
    return np.concatenate(out)
