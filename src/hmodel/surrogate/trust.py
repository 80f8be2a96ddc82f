"""How much a surrogate trusts each cell increment: distance to its training data, measured.

A network is accurate where it was trained densely and guesses elsewhere. The *trust score* of
a cell is the mean Euclidean distance, in the network's normalized input space (the inputs as
the first layer sees them), from the cell's inputs to its ``k`` nearest neighbours among a
reference sample of the training rows; the larger, the less the network has seen of such
cells. The reference sample (a few thousand rows) and the distribution of the score over held-out
rows are stored in the model file (:func:`fit_trust`, ``hmodel surrogate trust``), so that a
gate is a quantile: ``--gate 0.99`` sends the cells whose score exceeds the 99th percentile of
the held-out rows' scores to an exact cell solver (:class:`hmodel.surrogate.solver.SurrogateSolver`).

Whether the score ranks the real errors is measured, not assumed: :func:`fit_trust` reports,
on held-out rows with known answers, which share of the error the rows above each quantile of
the score hold, and the rank correlation between score and error (the surrogates page of the
documentation shows the shipped model's table).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import InputError
from .evaluation import truth_and_prediction
from .model import Surrogate

#: Quantile levels of the held-out scores stored in a model file (gates between them interpolate).
LEVELS = np.concatenate([np.linspace(0.0, 0.9, 10), np.linspace(0.91, 0.99, 9),
                         [0.995, 0.998, 0.999, 0.9995, 0.9999, 1.0]])
#: Top fractions of the held-out rows (by score) whose share of the error is reported.
TOP = (0.001, 0.01, 0.05, 0.1)


def row_errors(model: Surrogate, cols: dict[str, np.ndarray]) -> np.ndarray:
    """Error of each row: the RMS over the predicted outputs of (prediction − truth), each
    output in units of the standard deviation of its true increment over the rows."""
    y, p, before = truth_and_prediction(model, cols)
    scale = increment_spread(y, before)
    return np.sqrt(np.mean(((p - y) / scale) ** 2, axis=1))


def increment_spread(after: np.ndarray, before: np.ndarray) -> np.ndarray:
    """Standard deviation of each output's true increment over the rows (1 where it is 0): the
    unit of the errors and of an ensemble's disagreement."""
    scale = np.std(after - before, axis=0)
    scale[scale == 0] = 1.0
    return scale


def ranking(score: np.ndarray, error: np.ndarray) -> list[dict]:
    """For each top fraction f of :data:`TOP`: the share of the summed error and of the summed
    squared error held by the rows whose score is in the top f; plus the Spearman correlation
    of score and error (on every row). A score that ranks the errors perfectly puts the largest
    errors first; a random one gives shares equal to f."""
    from scipy.stats import spearmanr

    order = np.argsort(-score, kind="stable")
    e, e2 = error[order], error[order] ** 2
    rho = float(spearmanr(score, error).statistic)
    rows = []
    for f in TOP:
        n = max(1, int(round(f * len(score))))
        rows.append({"top_fraction": f, "rows": n, "share_of_error": float(e[:n].sum() / e.sum()),
                     "share_of_squared_error": float(e2[:n].sum() / e2.sum()),
                     "spearman": rho})
    return rows


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


def fit_trust(model: Surrogate, train: dict[str, np.ndarray], held_out: dict[str, np.ndarray],
              reference: int = 4096, k: int = 8, seed: int = 0) -> tuple[Surrogate, list[dict]]:
    """The model with a trust reference of ``reference`` rows drawn from its training rows
    ``train`` (database columns) and the quantiles of the score over the ``held_out`` rows;
    returns it with the ranking table (:func:`ranking`) measured on the held-out rows."""
    if reference < k or k < 1:
        raise InputError(f"the trust reference needs at least k >= 1 rows, got {reference} rows, k={k}")
    f = model.formulation
    X = np.asarray(f.inputs(train), float)
    if len(X) < reference:
        raise InputError(f"{len(X)} training rows for a reference of {reference}")
    idx = np.sort(np.random.default_rng(seed).choice(len(X), reference, replace=False))
    ref = model.x_scaler.transform(X[idx])
    meta = {**model.meta, "trust": {"k": k, "reference_rows": reference, "seed": seed}}
    out = replace(model, meta=meta, trust_reference=ref)
    s = scores(out, f.inputs(held_out))
    table = ranking(s, row_errors(model, held_out))
    out.meta["trust"].update({"held_out_rows": len(s), "ranking": table,
                              "quantiles": {"levels": LEVELS.tolist(),
                                            "scores": np.quantile(s, LEVELS).tolist()}})
    return out, table


# -- the ensemble's disagreement --------------------------------------------------------------
#
# Networks trained alike on the same rows with other seeds agree where the rows pin the answer
# down and scatter where they do not. The spread of the members' *increments* (each member's
# compliances applied to the cell's actual strain increment) is a score of each cell increment
# that sees where training left the networks uncertain, also inside the data, where a distance
# to the data sees nothing. (The spread of the raw compliances ranked the errors no better than
# the distance: most of the 24 numbers belong to contact regimes the increment does not use.)


def fingerprint(model: Surrogate) -> str:
    """SHA-256 of a model's weights (which network it is)."""
    import hashlib

    h = hashlib.sha256()
    for W, b in model.weights:
        h.update(np.ascontiguousarray(W).tobytes())
        h.update(np.ascontiguousarray(b).tobytes())
    return h.hexdigest()


def is_ensemble_trust(model: Surrogate) -> bool:
    """Whether a model's trust score is its ensemble's disagreement."""
    return (model.meta.get("trust") or {}).get("kind") == "ensemble"


#: The state fields whose increments the disagreement compares (α, N1, N2, T1 of the packed state).
INCREMENT_FIELDS = (2, 3, 4, 5)
#: ... and of a richer cell's summary state (:mod:`hmodel.surrogate.meso`): also V σ_nn, V σ_tt.
RICHER_INCREMENT_FIELDS = INCREMENT_FIELDS + (8, 9)


def increment_fields(formulation) -> tuple[tuple[int, ...], tuple[str, ...]]:
    """The state columns whose increments an ensemble's disagreement compares, and the
    database columns of their values after an increment."""
    names = ("alpha_next", "N1_next", "N2_next", "T1_next")
    if getattr(formulation, "richer", False):
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


def increment_scale(members: list[Surrogate]) -> np.ndarray | None:
    """The increments' scales of an ensemble gated on its disagreement (its members checked), or
    None for one network gated on its distance to the data; an ensemble without its
    disagreement as trust score is refused."""
    if is_ensemble_trust(members[0]):
        check_members(members)
        return np.asarray(members[0].meta["trust"]["increment_scale"])
    if len(members) > 1:
        raise InputError("an ensemble's gate needs its disagreement as trust score: add it with "
                         "'hmodel surrogate trust MODEL+MODEL+... SAMPLE --out FILE'")
    return None


def check_members(members: list[Surrogate]) -> None:
    """Refuse an ensemble other than the one its trust was measured on."""
    t = members[0].meta["trust"]
    if [fingerprint(m) for m in members] != t["members"]:
        raise InputError(f"the ensemble's trust was measured on {len(t['members'])} other networks; "
                         f"give the members in the order 'hmodel surrogate trust' was given them")


def fit_ensemble_trust(members: list[Surrogate], held_out: dict[str, np.ndarray]
                       ) -> tuple[list[Surrogate], list[dict]]:
    """The ensemble with its disagreement as trust score (stored with the first member: the
    members' fingerprints, the increments' scales and the quantiles of the score over the
    ``held_out`` rows), and the ranking table of the ensemble's errors on those rows. Needs a
    formulation whose networks see the state only and decode an increment from their outputs
    (``compliance``, ``meso``; a richer cell's V σ increments are compared too)."""
    if len(members) < 2:
        raise InputError("an ensemble's disagreement needs at least two networks")
    f = members[0].formulation
    if not hasattr(f, "advance"):
        raise InputError(f"an ensemble's disagreement needs compliance or meso networks, got {f.name!r}")
    for m in members[1:]:
        if m.formulation.to_dict() != f.to_dict():
            raise InputError("the ensemble's networks have different formulations or materials")
    held_out = getattr(f, "augment", lambda c: c)(held_out)
    X = np.asarray(f.inputs(held_out), float)
    outs = [m.forward(X, single=f.single_precision) for m in members]
    names = increment_fields(f)[1]
    y, before = (np.column_stack([held_out[k[:-5] if b else k] for k in names]) for b in (False, True))
    scale = increment_spread(y, before)
    # each member's increment, and the ensemble's as the solver makes it
    inc = [np.column_stack([f.decode(held_out, o)[k] for k in names]) - before for o in outs]
    mean = _ensemble_after(f, held_out, outs, names)
    s = disagreement(inc, scale)
    error = np.sqrt(np.mean(((mean - y) / scale) ** 2, axis=1))
    table = ranking(s, error)
    trust = {"kind": "ensemble", "members": [fingerprint(m) for m in members],
             "increment_scale": scale.tolist(), "held_out_rows": len(s), "ranking": table,
             "quantiles": {"levels": LEVELS.tolist(), "scores": np.quantile(s, LEVELS).tolist()}}
    first = replace(members[0], meta={**members[0].meta, "trust": trust}, trust_reference=None)
    return [first, *members[1:]], table


def _ensemble_after(f, held_out: dict[str, np.ndarray], outs: list[np.ndarray], names) -> np.ndarray:
    """The ensemble's state after each held-out row's increment, as the solver makes it: the
    members' increments averaged (``meso``) or their outputs averaged (``compliance``)."""
    if not hasattr(f, "mean_response"):
        return np.column_stack([f.decode(held_out, np.mean(outs, axis=0))[k] for k in names])
    from .meso import STATE_FIELDS

    v = np.column_stack([held_out[k] for k in STATE_FIELDS])
    dl = np.column_stack([held_out["l1_next"] - held_out["l1"], held_out["l2_next"] - held_out["l2"]])
    Y = np.mean([f.increment(o, held_out["deps1"], held_out["deps2"]) for o in outs], axis=0)
    new, _ = f.advance(v, Y, dl)
    return new[:, list(increment_fields(f)[0])]
