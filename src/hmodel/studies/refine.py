"""Active learning of a learned cell (``hmodel surrogate refine``).

A network is trusted where it was trained densely (:mod:`hmodel.surrogate.trust`); a REV drives
its cells through states that the training paths may have visited rarely. Each round:

1. runs the REV paths with the gate on (``--gate``: the cells whose trust score exceeds that
   quantile go to the exact solver) and collects the states the gate sent there;
2. solves increments from (a random subset of at most ``states`` of) those states with the
   exact cell solver, ``increments`` directions each with magnitudes spread over
   (0, ``magnitude``] as the training data's, and writes them as a sample folder (the usual
   manifest: material, cell solver, checksums, and the round's provenance);
3. fine-tunes the model (every member of an ensemble) on its training rows and every round's
   rows (weights, scalers and architecture kept), and refits its trust score on them (the
   distance reference, or the ensemble's disagreement on the held-out rows);
4. measures the new model, ungated, against the reference solver on the same paths: the largest
   deviation of q (relative to peak q) and of εv, as ``hmodel compare`` reports them.

Round 0 measures the starting model. Each round is written to ``OUT/round-K/`` (its rows, model
and summary); a round whose summary is there is not redone, so an interrupted run resumes at the
round it was in. The exact solver keeps the surrogate's cell state for the H-cell networks
(the ``compliance`` formulation) and the H-cell solvers, ``closed-form`` and ``dem:standard``.
A ``meso`` network of a richer cell is gated to its DEM cell (``dem:hexagon-center``, ...) with
the DEM state each cell carries beside its summary (:mod:`hmodel.surrogate.shadow`): the gated
states are those DEM cells, caught up with the strain the network took them through, and the new
rows are DEM increments from them, with the full DEM state as any DEM dataset's.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from ..cell.state import initial_lengths
from ..compare import deviations, run_path
from ..data import SCHEMA_VERSION, DatasetSpec
from ..data.generator import increment_rows
from ..data.store import sha256
from ..errors import InputError, SolverError
from ..io import write_outputs
from ..loading import standard_paths
from ..params import Params
from ..solvers import get_solver
from ..surrogate import modelfile
from ..surrogate.model import Surrogate
from ..surrogate.solver import SurrogateSolver, gated_solver
from ..surrogate.formulations.meso_rollout import LOSS_OPTIONS
from ..surrogate.training import TrainConfig, train, union
from ..surrogate.gate import fingerprint
from ..surrogate.trust import fit_ensemble_trust, fit_trust

#: The training settings a fine-tuning keeps from the model's own (the loss it was trained with:
#: a ``meso`` network's own options too, :class:`~hmodel.surrogate.formulations.meso.MesoTraining`).
LOSS_SETTINGS = ("loss", *LOSS_OPTIONS)
PATHS = ("drained", "undrained", "unload-reload")


@dataclass(frozen=True)
class RefineConfig:
    """Options of :func:`refine` (see the module docstring)."""

    exact: str = "closed-form"  #: the exact cell solver (``closed-form``, ``dem:standard``)
    reference: str = "closed-form"  #: the solver the rounds' errors are measured against
    paths: tuple[str, ...] = PATHS  #: ``hmodel compare``'s path names
    rounds: int = 3
    gate: float = 0.99
    states: int = 2000  #: most gated states solved per round
    increments: int = 24  #: increment directions per state
    magnitude: float = 2e-3  #: largest cell strain increment of the new rows
    epochs: int = 100  #: fine-tuning epochs per round (early stopping may end sooner)
    patience: int = 20
    lr: float = 1e-3
    axial: float = 0.1  #: axial strain of the biaxial paths
    step: float = 1e-3
    iso_step: float = 1e-4
    seed: int = 0
    extra: dict = field(default_factory=dict)  #: recorded with the rounds (e.g. the model's name)

    def __post_init__(self) -> None:
        known = [p.name for p in standard_paths()]
        for name in self.paths:
            if name not in known:
                raise InputError(f"unknown path {name!r} (known: {', '.join(known)})")
        if not self.paths:
            raise InputError("active learning needs at least one path")
        for name in ("rounds", "states", "increments", "epochs", "patience"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be at least 1, got {getattr(self, name)}")
        for name in ("magnitude", "lr", "axial", "step", "iso_step"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} must be a positive finite number, got {v!r}")
        if not 0.0 < self.gate <= 1.0:
            raise InputError(f"the gate is a quantile level in (0, 1], got {self.gate}")


def refine(model: "Surrogate | list[Surrogate]", sample: "str | Path | list", params: Params,
           config: RefineConfig, out: "str | Path", progress: Callable[[float], None] | None = None,
           log: Callable[[str], None] = lambda s: None) -> tuple[list[Surrogate], list[dict]]:
    """Active learning from ``model`` (one network, or an ensemble whose trust is its
    disagreement: every member is fine-tuned) and its training ``sample`` folder (or folders); returns the
    last round's members and one summary row per round (round 0: the starting model)."""
    from ..surrogate.training_rows import read_sample

    out = Path(out)
    samples = [Path(f) for f in (sample if isinstance(sample, (list, tuple)) else [sample])]
    members = list(model) if isinstance(model, (list, tuple)) else [model]
    exact = _exact_solver(config.exact)
    probe = gated_solver(SurrogateSolver(members), config.gate, exact)  # refuses what cannot gate
    probe.check(params)
    model_trust(members[0])
    parts = [read_sample(f, "train") for f in samples]
    for f, (_, info) in zip(samples, parts):
        if info["params"] != members[0].meta.get("params", info["params"]):
            raise InputError(f"{str(f)!r} holds rows of other material parameters than the model's")
    base = union([c for c, _ in parts])
    base_test = union([read_sample(f, "test")[0] for f in samples])
    specs = {s.name: s for s in standard_paths(config.axial)}
    specs = [specs[n] for n in config.paths]
    key = {**asdict(config), "paths": list(config.paths), "params": params.to_dict(),
           "model": [fingerprint(m) for m in members], "sample": [str(f) for f in samples]}
    t0 = time.perf_counter()
    references = {s.name: run_path(params, s, config.reference, config.step, config.iso_step)[0]
                  for s in specs}
    log(f"reference runs ({config.reference}) in {time.perf_counter() - t0:.1f} s")
    rows, parts = [], []
    summary = _load(out / "round-0", key)
    if summary is None:
        summary = {"round": 0, "rows_added": 0, "exact_rows": 0, **measure(members, params, specs,
                                                                            references, config)}
        _save(out / "round-0", key, summary, [])
    rows.append(summary)
    log(_line(summary))
    for r in range(1, config.rounds + 1):
        folder = out / f"round-{r}"
        done = _load(folder, key)
        if done is not None:
            members = [modelfile.load(folder / _member_file(k)) for k in range(len(members))]
            parts.append(_read_rows(folder / "rows"))
            rows.append(done)
            log(_line(done) + " (done before)")
        else:
            t = time.perf_counter()
            states, gate = _collect(members, exact, params, specs, config)
            if len(states) == 0:
                log(f"round {r}: the gate sent no cell to the exact solver; stopping")
                break
            pick = np.random.default_rng(config.seed + r)
            if len(states) > config.states:
                states = states[np.sort(pick.choice(len(states), config.states, replace=False))]
            new = _solve(states, exact, params, config)
            _write_rows(folder / "rows", new, params, config, r, pick)
            parts.append(_read_rows(folder / "rows"))
            cols = union([base] + [p[0] for p in parts])
            held = union([base_test] + [p[1] for p in parts])
            members, epochs = _fine_tune(members, cols, held, params, config, r)
            summary = {"round": r, "rows_added": len(new["deps1"]), "gated_states": len(states),
                       **gate, "epochs": epochs,
                       **measure(members, params, specs, references, config),
                       "seconds": time.perf_counter() - t}
            summary["exact_rows"] = rows[-1]["exact_rows"] + summary["rows_added"]
            _save(folder, key, summary, members)
            rows.append(summary)
            log(_line(summary))
        if progress is not None:
            progress(r / config.rounds)
    return members, rows


def fine_tune(members: list[Surrogate], cols: dict, params: Params, config: RefineConfig,
              r: int) -> tuple[list[Surrogate], int]:
    """Every member fine-tuned on ``cols`` as round ``r`` does it (its seeds; each member with
    the loss it was trained with), and the epochs run in all. The controls of the benchmarks
    call it on the start's own rows."""
    tuned, epochs = [], 0
    for k, m in enumerate(members):
        made = m.meta.get("config", {})
        # the loss it was trained with: a meso network's secant weighting and its rollouts along
        # the training rows' paths, or fine-tuning on single increments undoes what the
        # rollouts taught (docs/notes, 2026-12-02, the richer cell)
        cfg = replace(TrainConfig(formulation=m.formulation.name), epochs=config.epochs,
                      patience=config.patience, lr=config.lr, seed=config.seed + 1000 * r + k,
                      **{name: made[name] for name in LOSS_SETTINGS if name in made})
        m, hist = train(cols, params, cfg, init=m, cell=m.formulation.cell)
        m.meta.update(params=params.to_dict(), refined={"round": r, "rows": len(cols["deps1"])})
        tuned.append(m)
        epochs += len(hist)
    return tuned, epochs


def _fine_tune(members: list[Surrogate], cols: dict, held: dict, params: Params, config: RefineConfig,
               r: int) -> tuple[list[Surrogate], int]:
    """:func:`fine_tune`, with the trust score refitted as it was made (the distance reference,
    or the ensemble's disagreement on ``held``)."""
    trust = model_trust(members[0])
    tuned, epochs = fine_tune(members, cols, params, config, r)
    if trust.get("kind") == "ensemble":
        return fit_ensemble_trust(tuned, held)[0], epochs
    first, _ = fit_trust(tuned[0], cols, held, reference=trust["reference_rows"], k=trust["k"],
                         seed=config.seed + r)
    return [first, *tuned[1:]], epochs


def _member_file(k: int) -> str:
    """File name of an ensemble's member k in a round's folder (the first: model.safetensors)."""
    return "model.safetensors" if k == 0 else f"model-{k}.safetensors"


def model_trust(model: Surrogate) -> dict:
    """The trust settings a model was given (reference rows, k)."""
    trust = model.meta.get("trust")
    if not trust:
        raise InputError("active learning needs a model with a trust reference: add one with "
                         "'hmodel surrogate trust MODEL SAMPLE --out FILE'")
    return trust


def _exact_solver(spec: str):
    solver = get_solver(spec)
    solver.check_available()  # before any work: a refine run needs its DEM cells
    return solver


def measure(members, params, specs, references, config) -> dict:
    """Largest deviations of the ungated model from the reference on every path; a path the
    model cannot run to its end (a SolverError) counts as failed, its deviations NaN."""
    out, qs, evs = {}, [], []
    for spec in specs:
        try:
            res, _ = run_path(params, spec, SurrogateSolver(members), config.step, config.iso_step)
            dev = deviations(references[spec.name], res)
            q, ev = max(d["q_max_dev_rel"] for d in dev), max(d["eps_v_max_dev"] for d in dev)
        except SolverError:
            q = ev = math.nan
        out[f"q_dev_{spec.name}"], out[f"eps_v_dev_{spec.name}"] = q, ev
        qs.append(q)
        evs.append(ev)
    # np.max keeps a NaN: a failed path is no small error
    return {**out, "failed_paths": int(np.isnan(qs).sum()), "q_dev_max": float(np.max(qs)),
            "eps_v_dev_max": float(np.max(evs))}


def _collect(members, exact, params, specs, config) -> tuple[np.ndarray, dict]:
    """The distinct states the gate sent to the exact solver on every path, and the gate's counts."""
    solver = gated_solver(SurrogateSolver(members), config.gate, exact)
    solver.gated_states = []
    for spec in specs:
        try:
            run_path(params, spec, solver, config.step, config.iso_step)
        except SolverError:
            pass  # the states gated up to the failure are what the next round learns from
    c = solver.counts
    gate = {"gated_fraction": c["gated"] / max(c["gate_checked"], 1),
            "fallback_cells": c["fallback_cells"]}
    if not solver.gated_states:
        return np.zeros((0, exact.initial(params).values.shape[-1])), gate
    return np.unique(np.vstack(solver.gated_states), axis=0), gate


def _solve(states: np.ndarray, exact, params: Params, config: RefineConfig) -> dict[str, np.ndarray]:
    """Rows of the exact solver's increments from ``states`` (the REV's cells: α0 of params)."""
    spec = DatasetSpec(kind=2, n_increments=config.increments, magnitude=config.magnitude,
                       magnitude_min=0.0, substeps=1, solver=exact.name)
    P = len(states)
    l10, l20 = initial_lengths(params.radius, np.full(P, params.alpha0))
    table = increment_rows(spec, params, exact, states[:, None, :], (l10, l20), np.arange(P),
                           np.full(P, params.alpha0), np.zeros(P), np.zeros(1))
    from ..data.schema import column_array

    return {c: column_array(table, c) for c in table.column_names}


def _write_rows(folder: Path, cols: dict[str, np.ndarray], params: Params, config: RefineConfig,
                r: int, rng: np.random.Generator) -> None:
    """The round's rows as a sample folder: 90 % train, 10 % test (by state, so that a state's
    increments stay together)."""
    import pyarrow as pa

    from .. import __version__
    from ..data.schema import arrow_schema, to_arrow

    state = cols["path_id"]
    test_states = rng.random(int(state.max()) + 1) < 0.1
    masks = {"train": ~test_states[state], "test": test_states[state]}
    extra = cols.get("state_extra")
    schema = arrow_schema(n_extra=0 if extra is None else extra.shape[1])
    meta = {"format": "hmodel-cell-sample", "hmodel": __version__, "source": "active learning",
            "source_checksum": "", "schema_version": SCHEMA_VERSION, "kind": 2,
            "options": {"solver": config.exact, "n_increments": config.increments,
                        "magnitude": config.magnitude, "magnitude_min": 0.0, "substeps": 1},
            "params": params.to_dict(), "method": "active", "seed": config.seed + r,
            "rules": [], "columns": [f.name for f in schema], "round": r, "gate": config.gate,
            "files": {}}

    def writer(name: str):
        def write(path: Path) -> None:
            m = masks[name]
            table = pa.Table.from_arrays([to_arrow(cols[f.name][m], f.type) for f in schema], schema=schema)
            pq.write_table(table, path, compression="zstd")
            meta["files"][name] = {"file": path.name, "rows": int(m.sum()), "sha256": sha256(path)}
        return write

    write_outputs(folder, {"train.parquet": writer("train"), "test.parquet": writer("test"),
                           "manifest.json": lambda p: p.write_text(json.dumps(meta, indent=1) + "\n")})


def _read_rows(folder: Path) -> tuple[dict, dict]:
    from ..surrogate.training_rows import read_sample

    return read_sample(folder, "train")[0], read_sample(folder, "test")[0]


def _load(folder: Path, key: dict) -> dict | None:
    """A finished round's summary (None: not finished, or made with other settings)."""
    path = folder / "summary.json"
    if not path.is_file():
        return None
    saved = json.loads(path.read_text())
    return saved["summary"] if saved.get("config") == json.loads(json.dumps(key)) else None


def _save(folder: Path, key: dict, summary: dict, members: list[Surrogate]) -> None:
    writers = {_member_file(k): (lambda m: lambda p: modelfile.save(m, p))(m) for k, m in enumerate(members)}
    # the summary goes last: it marks the round as finished
    writers["summary.json"] = lambda p: p.write_text(json.dumps({"config": key, "summary": summary},
                                                                indent=1, default=float))
    write_outputs(folder, writers)


def _line(s: dict) -> str:
    extra = (f", {s['rows_added']:,} exact rows from {s['gated_states']:,} gated states "
             f"(gate fraction {100 * s['gated_fraction']:.2g} %)") if s["round"] else ""
    err = (f"max |dq|/peak q {100 * s['q_dev_max']:.3g} %, max |d eps_v| {s['eps_v_dev_max']:.2g}"
           if not s["failed_paths"] else f"{s['failed_paths']} path(s) failed")
    return f"round {s['round']}: {err}{extra}, {s['exact_rows']:,} exact rows in all"


def plot_rounds(rows: list[dict], path: "str | Path") -> None:
    """Error on every path against the exact rows added, one point per round."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    x = [r["exact_rows"] for r in rows]
    for key in sorted(k for k in rows[0] if k.startswith("q_dev_") and k != "q_dev_max"):
        ax.plot(x, [100 * r[key] for r in rows], "o-", label=key[6:])
    for r in rows:
        ax.annotate(str(r["round"]), (r["exact_rows"], 100 * r["q_dev_max"]), fontsize=8,
                    textcoords="offset points", xytext=(3, 3))
    ax.set_xlabel("exact-solver rows added")
    ax.set_ylabel("max |Δq| / peak q [%]")
    ax.set_yscale("log")
    ax.legend(title="path")
    ax.set_title("Active learning: error by round (numbers: rounds)")
    fig.savefig(path, dpi=130)
