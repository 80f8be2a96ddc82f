"""How much a surrogate trusts each cell increment: distance to its training data, measured.

A network is accurate where it was trained densely and guesses elsewhere. The *trust score* of
a cell is the mean Euclidean distance, in the network's normalized input space (the inputs as
the first layer sees them), from the cell's inputs to its ``k`` nearest neighbours among a
reference sample of the training rows; the larger, the less the network has seen of such
cells. The reference sample (a few thousand rows) and the distribution of the score over held-out
rows are stored in the model file (:func:`fit_trust`, ``hmodel surrogate trust``), so that a
gate is a quantile: ``--gate 0.99`` sends the cells whose score exceeds the 99th percentile of
the held-out rows' scores to an exact cell solver (the gate at run time: :mod:`hmodel.surrogate.gate`).

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
from .gate import disagreement, fingerprint, increment_fields, scores
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
    if not f.ensembles:
        raise InputError(f"an ensemble's disagreement needs compliance or meso networks, got {f.name!r}")
    for m in members[1:]:
        if m.formulation.to_dict() != f.to_dict():
            raise InputError("the ensemble's networks have different formulations or materials")
    held_out = f.augment(held_out)
    X = np.asarray(f.inputs(held_out), float)
    outs = [m.forward(X, single=f.single_precision) for m in members]
    names = increment_fields(f)[1]
    y, before = (np.column_stack([held_out[k[:-5] if b else k] for k in names]) for b in (False, True))
    scale = increment_spread(y, before)
    # each member's increment, and the ensemble's as the solver makes it
    inc = [np.column_stack([f.decode(held_out, o)[k] for k in names]) - before for o in outs]
    after = f.ensemble_decode(held_out, outs)  # the ensemble's, as the solver makes it
    mean = np.column_stack([after[k] for k in names])
    s = disagreement(inc, scale)
    error = np.sqrt(np.mean(((mean - y) / scale) ** 2, axis=1))
    table = ranking(s, error)
    trust = {"kind": "ensemble", "members": [fingerprint(m) for m in members],
             "increment_scale": scale.tolist(), "held_out_rows": len(s), "ranking": table,
             "quantiles": {"levels": LEVELS.tolist(), "scores": np.quantile(s, LEVELS).tolist()}}
    first = replace(members[0], meta={**members[0].meta, "trust": trust}, trust_reference=None)
    return [first, *members[1:]], table
