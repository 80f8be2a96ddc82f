"""The uncertainty gate at run time: which learned cell increments an exact solver takes over.

A gate compares a trust score of each cell (measured and stored by
:mod:`hmodel.surrogate.trust`) with a threshold, a quantile of the held-out rows' scores
(:func:`threshold`), and counts its decisions. Two kinds, one class each, built from the
model's stored trust by :func:`gate_for`:

- :class:`DistanceGate`: the distance of a cell's inputs to the training data (:func:`scores`);
  it depends on the state only, so it is decided once per state.
- :class:`DisagreementGate`: the spread of an ensemble's members' increments
  (:func:`increment_disagreement`); it depends on the increment, so it is decided per cell
  increment, Newton trials included, from the members' states after it.

Every gate offers ``mask(states, afters)`` (its decision, not counted), ``decide(states,
afters)`` (the same, counted in the ``gated`` and ``gate_checked`` entries of the solver's
``counts``) and ``summary()``, and declares ``per_increment``; the solvers that run them are
:class:`hmodel.surrogate.solver.SurrogateSolver` and
:class:`hmodel.surrogate.shadow.ShadowedSolver`.
"""

from __future__ import annotations

import hashlib
from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from ..errors import InputError
from .model import Surrogate

#: The state fields whose increments the disagreement compares (α, N1, N2, T1 of the packed state).
INCREMENT_FIELDS = (2, 3, 4, 5)
#: ... and of a richer cell's summary state (:mod:`hmodel.surrogate.formulations.meso_summary`):
#: also V σ_nn, V σ_tt.
RICHER_INCREMENT_FIELDS = INCREMENT_FIELDS + (8, 9)


class Gate(ABC):
    """A gate at quantile ``level`` (score threshold ``threshold``) whose decisions are counted
    in ``counts`` (the solver's counters: ``gated``, ``gate_checked``)."""

    #: Whether the decision depends on the increment (decided per cell increment, from the
    #: members' states after it) or on the state only (decided once per state).
    per_increment: ClassVar[bool]
    #: What one decision is about, as :meth:`summary` names it.
    decides: ClassVar[str]

    def __init__(self, level: float, threshold: float, counts: dict[str, int]):
        self.level, self.threshold, self.counts = level, threshold, counts

    @abstractmethod
    def score(self, states: np.ndarray, afters: list[np.ndarray] | None = None) -> np.ndarray:
        """Trust score (n,) of cells ``states`` (n, n_state), with the members' states after
        the increment ``afters`` where the gate is :attr:`per_increment`."""

    def mask(self, states: np.ndarray, afters: list[np.ndarray] | None = None) -> np.ndarray:
        """The cells whose score exceeds the threshold (not counted)."""
        return self.score(states, afters) > self.threshold

    def decide(self, states: np.ndarray, afters: list[np.ndarray] | None = None) -> np.ndarray:
        """:meth:`mask`, counted."""
        return self.count(self.mask(states, afters))

    def count(self, gated: np.ndarray) -> np.ndarray:
        """Count the decisions ``gated`` (a mask of cells) and return them."""
        self.counts["gated"] += int(gated.sum())
        self.counts["gate_checked"] += len(gated)
        return gated

    def summary(self) -> str:
        """How many cells the gate sent to the fallback solver, e.g. ``gate 0.99: 12 of 1,000
        cell states (1.2 %)``."""
        n, m = self.counts["gated"], self.counts["gate_checked"]
        return f"gate {self.level:g}: {n:,} of {m:,} {self.decides} ({100 * n / max(m, 1):.3g} %)"


class DistanceGate(Gate):
    """The gate on the distance of a cell's inputs to the training data of ``model``."""

    per_increment = False
    decides = "cell states"

    def __init__(self, model: Surrogate, level: float, threshold: float, counts: dict[str, int]):
        super().__init__(level, threshold, counts)
        self.model = model

    def score(self, states, afters=None):
        return scores(self.model, self.model.formulation.features(states))

    def inputs_mask(self, X: np.ndarray) -> np.ndarray:
        """:meth:`mask` of cells whose network inputs are ``X`` (n, n_inputs), not counted."""
        return scores(self.model, X) > self.threshold


class DisagreementGate(Gate):
    """The gate on an ensemble's disagreement about each cell increment (``formulation``: the
    members'; ``scale``: the increments' scales stored with the ensemble's trust)."""

    per_increment = True
    decides = "cell increments (Newton trials included)"

    def __init__(self, formulation, scale: np.ndarray, level: float, threshold: float,
                 counts: dict[str, int]):
        super().__init__(level, threshold, counts)
        self.formulation, self.scale = formulation, scale

    def score(self, states, afters=None):
        return increment_disagreement(self.formulation, states, afters, self.scale)


def gate_for(members: list[Surrogate], level: float, counts: dict[str, int]) -> Gate:
    """The gate at quantile ``level`` that the trust stored with ``members`` (one network, or an
    ensemble whose trust is its disagreement, its members checked) describes; an ensemble
    without its disagreement as trust score is refused."""
    limit = threshold(members[0], level)
    if is_ensemble_trust(members[0]):
        check_members(members)
        scale = np.asarray(members[0].meta["trust"]["increment_scale"])
        return DisagreementGate(members[0].formulation, scale, level, limit, counts)
    if len(members) > 1:
        raise InputError("an ensemble's gate needs its disagreement as trust score: add it with "
                         "'hmodel surrogate trust MODEL+MODEL+... SAMPLE --out FILE'")
    return DistanceGate(members[0], level, limit, counts)


def scores(model: Surrogate, X: np.ndarray) -> np.ndarray:
    """Trust score of inputs X (n, n_inputs): mean distance to the k nearest reference rows in
    the normalized input space (larger: less trusted). Needs a model with a reference sample."""
    if model.trust_reference is None:
        raise InputError("this surrogate has no trust reference: add one with "
                         "'hmodel surrogate trust MODEL SAMPLE --out FILE'")
    k = int(model.meta["trust"]["k"])
    z = model.x_scaler.transform(np.asarray(X, float))
    d, _ = model.trust_tree.query(z, k=k)
    return d.reshape(len(z), -1).mean(axis=1)


def threshold(model: Surrogate, gate: float) -> float:
    """The score above which a cell is gated at level ``gate`` (a quantile of the held-out rows'
    scores, in (0, 1])."""
    if not (0.0 < gate <= 1.0):
        raise InputError(f"the gate is a quantile level in (0, 1], got {gate}")
    if model.trust_reference is None and not is_ensemble_trust(model):
        scores(model, np.zeros((0, len(model.x_scaler.offset))))  # the one error message
    q = model.meta["trust"]["quantiles"]
    return float(np.interp(gate, q["levels"], q["scores"]))


def fingerprint(model: Surrogate) -> str:
    """SHA-256 of a model's weights (which network it is)."""
    h = hashlib.sha256()
    for W, b in model.weights:
        h.update(np.ascontiguousarray(W).tobytes())
        h.update(np.ascontiguousarray(b).tobytes())
    return h.hexdigest()


def is_ensemble_trust(model: Surrogate) -> bool:
    """Whether a model's trust score is its ensemble's disagreement."""
    return (model.meta.get("trust") or {}).get("kind") == "ensemble"


def check_members(members: list[Surrogate]) -> None:
    """Refuse an ensemble other than the one its trust was measured on."""
    t = members[0].meta["trust"]
    if [fingerprint(m) for m in members] != t["members"]:
        raise InputError(f"the ensemble's trust was measured on {len(t['members'])} other networks; "
                         f"give the members in the order 'hmodel surrogate trust' was given them")


def increment_fields(formulation) -> tuple[tuple[int, ...], tuple[str, ...]]:
    """The state columns whose increments an ensemble's disagreement compares, and the
    database columns of their values after an increment."""
    names = ("alpha_next", "N1_next", "N2_next", "T1_next")
    if formulation.richer:
        return RICHER_INCREMENT_FIELDS, names + ("Vs_nn_next", "Vs_tt_next")
    return INCREMENT_FIELDS, names


def disagreement(increments: list[np.ndarray], scale: np.ndarray) -> np.ndarray:
    """Trust score of cell increments from every member's increment (K arrays (n, m)): the RMS
    over the fields of the members' standard deviation, each in units of ``scale`` (m,)."""
    spread = np.std(np.stack(increments), axis=0) / scale
    return np.sqrt(np.mean(spread ** 2, axis=1))


def increment_disagreement(formulation, v: np.ndarray, afters: list[np.ndarray], scale: np.ndarray) -> np.ndarray:
    """Trust score of cell increments from states ``v`` (n, n_state): the :func:`disagreement`
    of the members' states after them (K arrays like ``v``) on the compared fields."""
    cols = list(increment_fields(formulation)[0])
    return disagreement([a[:, cols] - v[:, cols] for a in afters], scale)
