"""Where a path enters the bifurcation domain and where it loses controllability, from the
d²W of its loading increments and the probes' minimum at its probed states: the rules, and the
result of a path's analysis (:class:`PathStability`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..loading.result import COMPONENTS
from .work import loading_work, second_order_work


@dataclass
class PathStability:
    """Stability along a path (a biaxial test or a loading program): the path table, the
    loading increments' d²W, the probe minimum at the probed states, envelopes at requested
    strains, and the located points.

    ``shear_strain`` and the located points are axial strains since consolidation (eps11
    minus its value there); ``*_step`` give the same points as rows (``step``) of the table,
    unambiguous on cyclic paths."""

    result: "object"            # PathResult of the whole path
    shear_strain: np.ndarray    # axial strain since consolidation, per row after it
    loading_w: np.ndarray       # normalized d²W of each increment after consolidation
    check_strain: np.ndarray    # axial strain of each probed state
    check_min_w: np.ndarray     # min over probe directions of normalized d²W there
    envelopes: dict             # axial strain -> (strain Envelope, stress Envelope)
    bifurcation: float          # first state with some d²W <= 0, probes or loading (NaN: none)
    controllability: float      # first strain where the loading increment's d²W <= 0 and stays
    check_step: np.ndarray = field(default_factory=lambda: np.empty(0, int))
    check_magnitude: np.ndarray = field(default_factory=lambda: np.empty(0))
    bifurcation_step: float = float("nan")
    controllability_step: float = float("nan")
    bifurcation_by: str = ""    # "probes" or "loading increment"
    controllability_by: str = "loading increments"  # or "unsolvable increment" (a program's end)


def first_sign_change(x: np.ndarray, values: np.ndarray, persist: int = 5) -> float:
    """First abscissa where ``values`` becomes ≤ 0 after being > 0 and stays ≤ 0 for
    ``persist`` values (or to the end), by linear interpolation; NaN when it never does.

    ``persist`` skips the isolated negative increments of single cell events (a contact
    opening is a small stress drop), which are not a loss of controllability of the sample."""
    v = np.asarray(values, float)
    i = _first_persistent(v, persist)
    if i is None:
        return float("nan")
    x0, x1, v0, v1 = x[i - 1], x[i], v[i - 1], v[i]
    return float(x0 + (x1 - x0) * v0 / (v0 - v1)) if v0 != v1 else float(x1)


#: How the loss of controllability is located along a path
#: (:func:`~hmodel.stability.analysis.along_program`).
RULES = ("increments", "secant")


def _rule(rule: str | None, n_components: int) -> str:
    """The rule of ``rule`` (None: ``increments`` in 2D, ``secant`` in 3D), checked."""
    rule = rule or ("secant" if n_components == 6 else "increments")
    if rule not in RULES:
        raise InputError(f"the controllability rule must be one of {', '.join(RULES)}, got {rule!r}")
    return rule


def _first_secant_loss(eps: np.ndarray, sig: np.ndarray, lw: np.ndarray,
                       segment: np.ndarray | None = None) -> int | None:
    """Row i of the first state, after a loading increment of d²W > 0, from which the path's
    secant work (σ_j − σ_i):(ε_j − ε_i) is ≤ 0 for every later state j of the same stage
    (``segment`` (n,): a label per row, the stage of a row; None: one stage): the path never
    makes up, under its stage's control, what it had at i (on a triaxial test, the peak of q).
    A cell event that the path makes up later, in one increment or in many, is skipped,
    whatever the increments' size; a drop made up by no later state is not, however stiffly the
    path reloads between drops (the sawtooth of the 3D model, docs/stability.md)."""
    segment = np.zeros(len(eps), int) if segment is None else np.asarray(segment)
    pos = np.flatnonzero(lw > 0)
    if not len(pos):
        return None
    for i in np.flatnonzero((lw <= 0) & (np.arange(len(lw)) > pos[0])):
        # the increment i -> i + 1 belongs to the stage of row i + 1; its states from there
        same = segment[i + 1:] == segment[i + 1]
        end = i + 1 + (int(np.argmin(same)) if not same.all() else len(same))
        w = second_order_work(eps[i + 1:end] - eps[i], sig[i + 1:end] - sig[i])[0]
        if np.all(w <= 0):
            return int(i)
    return None


def _located(res, probed: dict, envs: dict, loading_probe: bool,
             rule: str = "increments") -> PathStability:
    """Locate the entry into the bifurcation domain and the loss of controllability on a path:
    by the loading increments' own d²W (``rule="increments"``, :func:`first_sign_change`) or by
    the path's secant work (``"secant"``, :func:`_first_secant_loss`)."""
    cons = res["stage"] == "consolidation"
    first = int(np.flatnonzero(~cons)[0]) if (~cons).any() else len(res)
    start = max(first - 1, 0)  # the consolidated state, then every state after it
    comps = _components(res)  # the state's order: the probed states' strains are its rows
    eps = np.column_stack([res[f"eps{c}"] for c in comps])[start:]
    sig = np.column_stack([res[f"sig{c}"] for c in comps])[start:]
    steps = res["step"][start:]
    _, lw = loading_work(eps, sig)  # lw[i]: increment from row i to row i + 1
    e0 = eps[0, 0]
    x = eps[1:, 0] - e0
    # min normalized d²W over the probes from each state (NaN: not probed)
    rowmin = np.full(len(eps), np.nan)
    rowmag = np.full(len(eps), np.nan)
    index = {tuple(r): i for i, r in enumerate(eps)}
    for key, (w, m) in probed.items():
        i = index.get(key)
        if i is not None:
            rowmin[i], rowmag[i] = w, m
    checked = np.flatnonzero(np.isfinite(rowmin))
    by_probe = np.flatnonzero(rowmin <= 0)
    by_load = np.flatnonzero(lw <= 0) if loading_probe else np.empty(0, int)
    candidates = [(int(by_probe[0]), "probes")] if len(by_probe) else []
    if len(by_load):
        candidates.append((int(by_load[0]), "loading increment"))  # a probe from its start row
    entry, by = min(candidates) if candidates else (None, "")
    xs = np.r_[0.0, x]
    lost_step = float("nan")
    if rule == "secant":
        tags = [res["stage"][start:]] + ([res["cycle"][start:]] if "cycle" in res.columns else [])
        change = np.zeros(len(eps), bool)
        for t in tags:
            change[1:] |= t[1:] != t[:-1]
        i = _first_secant_loss(eps, sig, lw, np.cumsum(change))
        lost = float(xs[i]) if i is not None else float("nan")
        lost_step = float(steps[i]) if i is not None else float("nan")
    else:
        lost = first_sign_change(x, lw)
        if math.isfinite(lost):
            i = _first_persistent(lw)
            lost_step = float(steps[i + 1]) if i is not None else float("nan")
    return PathStability(
        res, x, lw, xs[checked], rowmin[checked], envs,
        float(xs[entry]) if entry is not None else float("nan"), lost,
        steps[checked], rowmag[checked],
        float(steps[entry]) if entry is not None else float("nan"), lost_step, by,
        controllability_by="loading increments" if rule == "increments" else "secant work")


def _components(res) -> tuple[str, ...]:
    """The Voigt components of a path table's states, in the REV's order (2D or 3D)."""
    return COMPONENTS[6 if "eps33" in res.columns else 3]


def _first_persistent(values: np.ndarray, persist: int = 5) -> int | None:
    """Index of the increment where :func:`first_sign_change` locates the sign change."""
    v = np.asarray(values, float)
    pos = np.flatnonzero(v > 0)
    if not len(pos):
        return None
    for i in np.flatnonzero((v <= 0) & (np.arange(len(v)) > pos[0])):
        if np.all(v[i:i + persist] <= 0):
            return int(i)
    return None
