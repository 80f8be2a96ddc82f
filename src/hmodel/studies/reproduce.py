"""``hmodel reproduce``: the whole study in one command, written as a self-contained HTML report.

Steps: (1) the engine's drained biaxial curves at 100, 200 and 400 kPa (report Fig. 1.7);
(2) a training database of REV-scale increments (:data:`hmodel.surrogate.shipped.REV_DATASET`;
reduced in ``--quick``, at the report's scale of ≈10⁷ rows in the full run); (3) a surrogate
(``--quick``: the shipped one, evaluated on the new rows; full: trained on a 600k-row sample of
them with the shipped model's recipe, saved as ``surrogate.safetensors``); (4) the macro
comparison of the ANN-based H-model with the closed form on every path, with timings; (5) in the
full run, the report's Table 2.1 study at its scale beside the report's Fig. 2.7 numbers
(:func:`table21`, about two hours on two cores). Every figure is a PNG beside ``report.html``, every
table a CSV; the HTML embeds the figures, so the file alone can be sent.
"""

from __future__ import annotations

import base64
import html
import math
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, is_dataclass, replace
from pathlib import Path

import numpy as np

from .. import __version__
from ..params import Params


@dataclass(frozen=True)
class Plan:
    quick: bool
    n_theta: int
    axial: float
    step: float
    data_directions: int
    data_alpha0: str
    train_rows: int = 0  #: 0: use the shipped surrogate instead of training one
    #: Table 2.1 beside the report's (full run): training-set sizes of the sweep (empty: skipped)
    table21_sizes: tuple[int, ...] = ()
    table21_minutes: float = 3.0  #: training-time cap of each of its runs


QUICK = Plan(True, 360, 0.1, 1e-3, 8, "40:50:5")
FULL = Plan(False, 360, 0.1, 1e-4, 211, "32:88:2", 600_000, (6_000, 60_000, 600_000))


def _img(path: Path, caption: str) -> str:
    """The figure embedded, with what it shows and the file it is beside the report as."""
    data = base64.b64encode(path.read_bytes()).decode()
    return (f'<figure><img src="data:image/png;base64,{data}" style="max-width:100%"><figcaption>'
            f'{html.escape(caption)} <span class="file">({html.escape(path.name)})</span></figcaption></figure>')


#: What each comparison path is, for the captions of its figure.
PATH_WHAT = {"isotropic": "isotropic compression", "drained": "drained biaxial compression",
             "undrained": "undrained biaxial compression",
             "unload-reload": "drained biaxial compression with an unloading–reloading cycle",
             "oedometric": "oedometric compression (ε22 = 0)",
             "rotation": "isochoric strain whose principal axes rotate (ε12 ≠ 0)"}

#: The generator's options as ``hmodel data generate`` names them, and what they set.
DATASET_OPTIONS = {
    "kind": ("dataset", "1: monotonic cell paths; 2: increments from their states; 3: from a REV's cells' states"),
    "n_directions": ("--directions", "cell-strain directions θ of the paths"),
    "theta_min": ("--theta (min)", "least θ [°]"), "theta_max": ("--theta (max)", "largest θ [°]"),
    "alpha0_min": ("--alpha0 (min)", "least initial opening angle α0 [°]"),
    "alpha0_max": ("--alpha0 (max)", "largest α0 [°]"), "alpha0_step": ("--alpha0 (step)", "step of α0 [°]"),
    "max_strain": ("--max-strain", "total cell strain of a path"),
    "step": ("--step", "strain step along a path"),
    "start_every": ("--start-every", "cell strain between the start states of the increments"),
    "magnitude": ("--magnitude", "strain magnitude of an increment (largest)"),
    "magnitude_min": ("--magnitude-min", "least magnitude (spread uniformly up to --magnitude)"),
    "n_increments": ("--increments", "increment directions over [0°, 360°)"),
    "substeps": ("--substeps", "equal sub-steps of an increment"),
    "shard_rows": ("--shard-rows", "rows per shard file"),
    "solver": ("--solver", "cell solver that computed the rows"),
    "from_unloaded": ("--from-unloaded", "the unloaded cell is a start state too"),
    "prestrain": ("--prestrain", "isotropic cell strain before every path"),
    "rev_paths": ("--rev-paths", "the REV's loading paths (dataset 3)"),
}


def _value(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v) if v not in ("", None) else "—"


def _options_table(options: dict, names: dict | None = None) -> str:
    """Options as a table of name, value and (where ``names`` knows it) what it sets."""
    names = names or {}
    rows = [{"option": names.get(k, (k, ""))[0], "value": _value(v), "meaning": names.get(k, ("", ""))[1]}
            for k, v in options.items()]
    if not any(r["meaning"] for r in rows):
        rows = [{"option": r["option"], "value": r["value"]} for r in rows]
    return _table(rows)


def _surrogate_text(solver_spec: str, formulation: str, trained: bool) -> str:
    """The learned cell the report compares, in words (not the solver spec twice)."""
    name = solver_spec.partition(":")[2]
    what = ("the surrogate trained here (surrogate.safetensors)" if trained
            else "the shipped surrogate" if not name else f"the surrogate {name}")
    return what + (f", {formulation} formulation" if formulation else "")


#: A drop of q that shows in Fig. 1.7: at least this fraction of q (the few later ones, two
#: cells at a time near the peak, are a hundred times smaller).
VISIBLE_DROP = 0.005


def _cell_events(result) -> list[dict]:
    """The increments before the peak of q in which q falls visibly, per material point, with
    the cells that opened in them: the small drops of Fig. 1.7."""
    n_theta = int(result.meta.get("params", {}).get("n_theta", 0))
    events = []
    for b in range(result.n_points):
        cons, shear = result.point(b).stage("consolidation"), result.point(b).stage("shear")
        q = shear["q"]
        if not len(cons) or len(q) < 2:
            continue
        peak = int(np.argmax(q))
        for k in np.flatnonzero(np.diff(q[:peak + 1]) < -VISIBLE_DROP * q[1:peak + 1]) + 1:
            events.append({"p0": float(cons["p"][-1]), "eps": float(shear["eps11"][k] - cons["eps11"][-1]),
                           "q_p": (float(shear["q_p"][k - 1]), float(shear["q_p"][k])),
                           "dq": float(q[k] - q[k - 1]), "n_theta": n_theta,
                           "opened": round(float(shear["frac_open"][k] - shear["frac_open"][k - 1]) * n_theta)})
    return events


def _fig17_caption(result) -> str:
    """What Fig. 1.7 shows, and what its small drops before the peak are."""
    text = ("The report's Fig. 1.7 recomputed: drained biaxial tests at p0 = 100, 200 and 400 kPa with "
            "the closed-form cells: stress ratio q/p, volumetric strain and deviatoric stress q against "
            "the axial strain after consolidation.")
    events = _cell_events(result)
    if not events or result.meta.get("params", {}).get("sliding_rhs") != "report":
        return text
    each = "; ".join(f"p0 = {e['p0'] / 1e3:g} kPa, Δε11 = {100 * e['eps']:.2f} %: {e['opened']} of "
                     f"{e['n_theta']} cells open, q/p {e['q_p'][0]:.3f} → {e['q_p'][1]:.3f}, "
                     f"Δq = {e['dq'] / 1e3:.1f} kPa" for e in events)
    return (text + " The small drops before the peak are cell events, not numerical noise: with the "
            "report's λ of eq. 1.10 (sliding_rhs=report, the default) a cell whose contact starts to "
            "slide with T1 < 0 opens at once and stops carrying force, and neighbouring directions do "
            f"so in the same increment ({each}). With sliding_rhs=equilibrium the same cells start "
            "sliding at the same strains without opening, and the curves are smooth, with the same "
            "peak q/p.")


def _compare_caption(spec) -> str:
    p0 = ", ".join(f"{p / 1e3:g}" for p in spec.p0)
    x = "against the state along the path" if spec.name == "rotation" else "against ε11"
    scale = ("the peak mean stress, as q stays at round-off" if spec.name == "isotropic"
             else "the closed form's peak q")
    return (f"{spec.name}: {PATH_WHAT.get(spec.name, spec.name)} from p0 = {p0} kPa. Closed form (solid) "
            f"and surrogate (dashed): q and εv {x} and the stress path; errors of the surrogate row by "
            f"row: Δq relative to {scale} (left axis) and Δεv in % strain (dotted, right axis).")


def _speed_text(dev_rows: list[dict]) -> str:
    """The speed ratios' range and why they are below 1 on this cell."""
    ratios = [r["speed ratio"] for r in dev_rows if math.isfinite(r["speed ratio"])]
    if not ratios:
        return ""
    return (f"Speed ratios here: {min(ratios):.2f}–{max(ratios):.2f}. Below 1 the surrogate is slower, "
            "and on this cell it is by design: a closed-form cell costs about a hundred flops per state, "
            "the network about 10⁴. This comparison measures what the network costs and how closely it "
            "reproduces a known answer; a learned cell pays off for cells without a closed form (the DEM "
            "cells, docs/dem.md), whose every increment is otherwise a DEM simulation.")


def _comparison_rows(dev_rows: list[dict]) -> list[dict]:
    """The deviation rows as the report's table shows them (deviations.csv keeps its columns)."""
    head = {"in report": "in the report (§3.1)", "speed ratio": "speed ratio (closed form ÷ surrogate)"}
    return [{head.get(k, k): ("yes" if v else "no") if k == "in report" else v for k, v in r.items()}
            for r in dev_rows]


def _threads(params: Params, solver, n_points: int) -> str:
    """What a timed comparison run ran, for the report's speed column: the loading path, the
    Numba threads of its kernel (one per material point, at most Numba's) and the BLAS threads
    of the network's forward pass."""
    import numba

    from ..cell import ClosedFormSolver
    from ..loading.compiled import supports
    from ..rev import Rev
    from ..surrogate.model import SPLIT_ROWS

    def path(s) -> str:
        if not supports(Rev(params, s)):
            return "generic driver, 1 thread"
        n = min(n_points, numba.get_num_threads())
        return f"compiled kernel on {n} Numba thread{'s' if n > 1 else ''}"
    rows = n_points * params.n_theta
    net = "1 BLAS thread" if rows < SPLIT_ROWS else "its blocks shared among the BLAS threads allowed"
    return f"closed form: {path(ClosedFormSolver())}; surrogate: {path(solver)}, network on {net}"


def _conditions() -> str:
    """The machine the times were taken on, and how busy other programs kept it."""
    return (f"Times of this machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} "
            f"(1 min) when the comparison started; programs running beside it take cores from "
            f"these runs.")


def _table(rows: list[dict], digits: int = 4) -> str:
    if not rows:
        return "<p>(no rows)</p>"
    keys = list(dict.fromkeys(k for r in rows for k in r))
    cell = lambda v: f"<td>{v:.{digits}g}</td>" if isinstance(v, float) else f"<td>{html.escape(str(v))}</td>"  # noqa: E731
    head = "".join(f"<th>{html.escape(str(k))}</th>" for k in keys)
    body = "".join("<tr>" + "".join(cell(r.get(k, "")) for k in keys) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def table21(work: Path, sizes: tuple[int, ...], minutes: float, depths=None, d1_spec=None, d2_spec=None,
            n_test: int = 100_000) -> tuple[list[dict], dict]:
    """The Table 2.1 sweep (:mod:`hmodel.studies.sweep`) on a report-scale Dataset 2 (the
    generator's defaults unless ``d2_spec``), scored on it and on Dataset 1, in both input
    conventions; returns its rows and the writers of ``table-2-1.csv``, ``fig-2-7.csv`` and
    ``table-2-1.png``."""
    from ..data import Dataset, DatasetSpec, generate
    from ..io import write_rows
    from ..surrogate.training import TrainConfig
    from ..surrogate.training_rows import read_rows
    from .sweep import DEPTHS, beside_report, plot_sweep, run_sweep

    d1 = generate(d1_spec or DatasetSpec(kind=1), Params(), work / "d1", workers=os.cpu_count() or 1)
    d2 = generate(d2_spec or DatasetSpec(kind=2), Params(), work / "d2", workers=os.cpu_count() or 1)
    test1, _ = read_rows(d1.folder, "test", min(n_test, d1.n_rows - 1), 0)  # as the CLI's --dataset1
    base = TrainConfig(formulation="report", normalization="minmax", epochs=200, patience=20,
                       max_minutes=minutes)
    rows = run_sweep(Dataset.open(d2.folder), base, depths or DEPTHS, sizes=sizes,
                     n_test=min(n_test, d2.n_rows // 10), inputs=("before", "after"), tests={"d1": test1})
    return rows, {"table-2-1.csv": lambda p: write_rows(rows, p),
                  "fig-2-7.csv": lambda p: write_rows(beside_report(rows), p),
                  "table-2-1.png": lambda p: plot_sweep(rows, p)}


@dataclass
class _Study:
    """What the steps of one :func:`reproduce` run share: the plan, the parameters, the work
    folder, the files to write (name -> writer, in order) and the timings table."""
    plan: Plan
    params: Params
    work: Path
    tick: Callable[[float], None]
    files: dict = field(default_factory=dict)
    timings: list = field(default_factory=list)
    captions: dict = field(default_factory=dict)  #: figure file name -> what it shows

    def timed(self, step: str, t0: float) -> None:
        """Records ``step`` as taking from ``t0`` (``time.perf_counter``) to now."""
        self.timings.append({"step": step, "seconds": time.perf_counter() - t0})


def _engine(study: _Study) -> None:
    """1. Engine: Fig. 1.7, after a warm-up (Numba's first compilation is timed apart)."""
    from ..compare import warm_up
    from ..loading import run_biaxial
    from ..plotting import plot_result

    plan, params = study.plan, study.params
    warm = warm_up(params, ["closed-form"], plan.step, 1e-4)
    study.timings.append({"step": "warm-up of the closed form (Numba compilation on a fresh install)",
                          "seconds": warm["closed-form"]})
    t = time.perf_counter()
    fig17 = run_biaxial(params, [1e5, 2e5, 4e5], plan.axial)
    study.timed("drained biaxial, 3 pressures (closed form)", t)
    study.files["fig-1-7.png"] = lambda p: plot_result(fig17, p)
    study.captions["fig-1-7.png"] = _fig17_caption(fig17)
    study.files["fig-1-7.csv"] = fig17.to_csv
    study.tick(0.1)


def _database(study: _Study):
    """2. Database: REV-scale increments (reduced grid in --quick); returns it and its spec."""
    from ..data import generate
    from ..surrogate.shipped import REV_DATASET

    a = [float(x) for x in study.plan.data_alpha0.split(":")]
    spec = replace(REV_DATASET, n_directions=study.plan.data_directions, alpha0_min=a[0],
                   alpha0_max=a[1], alpha0_step=a[2])
    t = time.perf_counter()
    ds = generate(spec, Params(), study.work / "dataset", workers=os.cpu_count() or 1)
    study.timed(f"database generation ({ds.n_rows:,} rows)", t)
    study.tick(0.2)
    return ds, spec


def _surrogate(study: _Study, ds, solver_spec: str):
    """3. Surrogate: trained on the new database (full) or the shipped one, evaluated on new
    rows; returns the solver, its spec and the metrics."""
    from ..compare import warm_up
    from ..data.sampling import write_split
    from ..io import write_rows
    from ..solvers import get_solver
    from ..surrogate import save
    from ..surrogate.evaluation import evaluate, parity_plot
    from ..surrogate.shipped import DEFAULT_TRAINING
    from ..surrogate.training import train_on_sample
    from ..surrogate.training_rows import read_rows

    plan, work, files = study.plan, study.work, study.files
    if plan.train_rows:
        t = time.perf_counter()
        n_test = min(100_000, ds.n_rows // 10)
        write_split(ds, work / "sample", min(plan.train_rows, ds.n_rows // 2), n_test, "random", 0)
        model, _ = train_on_sample(work / "sample", DEFAULT_TRAINING)
        study.timed(f"training ({plan.train_rows:,} rows, {model.meta['epochs_run']} epochs)", t)
        solver_spec = "surrogate:" + str(work / "surrogate.safetensors")
        save(model, work / "surrogate.safetensors")
        files["surrogate.safetensors"] = lambda p: shutil.copyfile(work / "surrogate.safetensors", p)
    solver = get_solver(solver_spec)
    study.timings.append({"step": f"warm-up of {solver.name} (compilation)",
                          "seconds": warm_up(study.params, [solver], plan.step, 1e-4)[solver.name]})
    model = solver.model
    cols, _ = read_rows(work / "sample" if plan.train_rows else ds.folder, n=min(100_000, ds.n_rows), seed=0)
    metrics = evaluate(model, cols, "new rows")
    files["parity.png"] = lambda p: parity_plot(model, cols, p, "surrogate on new rows")
    study.captions["parity.png"] = (
        f"The surrogate's prediction against the closed form's value on {len(next(iter(cols.values()))):,} "
        "rows of the database above, per output: the cell state after the increment (top) and the "
        "increment itself (bottom); the dashed line is equality.")
    files["surrogate-metrics.csv"] = lambda p: write_rows(metrics, p)
    study.tick(0.4)
    return solver, solver_spec, metrics


def _comparison(study: _Study, solver):
    """4. Macro comparison and timings on every standard path; returns the deviation rows, the
    paths and the machine's conditions."""
    from ..compare import compare_path, plot_overlay
    from ..io import write_rows
    from ..loading import standard_paths

    params, plan = study.params, study.plan
    dev_rows = []
    specs = standard_paths(plan.axial)
    conditions = _conditions()
    for i, path_spec in enumerate(specs):
        ref, res, devs, st = compare_path(params, path_spec, solver, plan.step, 1e-4)
        base = {"path": path_spec.name, "in report": path_spec.in_report, "status": st["status"]}
        times = {"closed form [s]": st["seconds_reference"], "surrogate [s]": st["seconds_other"],
                 "speed ratio": st["seconds_reference"] / st["seconds_other"],
                 "ran": _threads(params, solver, len(path_spec.p0))}
        if res is None:
            dev_rows.append({**base, "p0 [kPa]": ", ".join(f"{p / 1e3:g}" for p in path_spec.p0), **times})
        for d in devs:
            dev_rows.append({**base, "p0 [kPa]": path_spec.p0[d["point"]] / 1e3,
                             "max |Δq| / peak q [%]": 100 * d["q_max_dev_rel"],
                             "RMS Δq / peak q [%]": 100 * d["q_rms_dev_rel"],
                             "max |Δεv| [% strain]": 100 * d["eps_v_max_dev"], **times})
        if res is not None:
            study.files[f"compare-{path_spec.name}.png"] = (lambda n, x, y: lambda p: plot_overlay(
                n, x, y, ("closed form", "surrogate"), p))(path_spec.name, ref, res)
            study.captions[f"compare-{path_spec.name}.png"] = _compare_caption(path_spec)
        study.tick(0.4 + 0.55 * (i + 1) / len(specs))
    study.files["deviations.csv"] = lambda p: write_rows(dev_rows, p)
    return dev_rows, specs, conditions


def _table21_step(study: _Study) -> list[dict]:
    """5. The Table 2.1 sweep of the full run (none in --quick); returns its rows."""
    if not study.plan.table21_sizes:
        return []
    t = time.perf_counter()
    t21, t21_files = table21(study.work / "table21", study.plan.table21_sizes, study.plan.table21_minutes)
    study.files.update(t21_files)
    study.captions["table-2-1.png"] = (
        "1 − R² on the test rows of the angle and the three forces against the number of hidden layers, "
        "per training-set size and loss (solid: MSE, dashed: MAE); circles: inputs as the model runs them "
        "(forces before the increment), crosses: as the report's code feeds them (forces after).")
    study.timed(f"Table 2.1 sweep ({len(t21)} trainings)", t)
    return t21


def _report_writer(study: _Study, *, quick: bool, solver_spec: str, model, ds, spec, metrics,
                   dev_rows, specs, conditions, t21):
    """The writer of ``report.html``: every step's tables and the figures written before it."""
    from ..surrogate.shipped import DEFAULT_TRAINING

    plan, files, timings, captions = study.plan, study.files, study.timings, study.captions
    formulation = model.meta.get("formulation", {}).get("name", "")
    in_report = [s.name for s in specs if s.in_report]
    new_paths = [s.name for s in specs if not s.in_report]
    n_points = sum(len(s.p0) for s in specs)
    several = ", ".join(f"{s.name} at {len(s.p0)} pressures" for s in specs if len(s.p0) > 1)
    several = f" ({several})" if several else ""

    def fig(p: Path, name: str) -> str:
        return _img(p.parent / name, captions[name])

    def write_html(p: Path) -> None:
        figs = {name for name in files if name.endswith(".png")}
        if plan.train_rows:
            cfg = DEFAULT_TRAINING
            recipe = asdict(cfg) if is_dataclass(cfg) else {}
            default = asdict(type(cfg)()) if is_dataclass(cfg) else {}
            trained = ("<p>Trained here with the shipped model's recipe (its options that differ from "
                       "the defaults of <code>hmodel surrogate train</code>):</p>"
                       + _options_table({k: v for k, v in recipe.items() if default.get(k) != v}))
        else:
            trained = "<p>The shipped model.</p>"
        body = [f"<h1>hmodel {html.escape(__version__)}: the H-model and its neural surrogate</h1>",
                f"<p>{'Quick run' if quick else 'Full run'}; nθ = {plan.n_theta}, increments {plan.step:g} "
                f"(consolidation 1e-4); learned cell compared with the closed form: "
                f"{html.escape(_surrogate_text(solver_spec, formulation, bool(plan.train_rows)))}.</p>",
                "<h2>1. Drained biaxial tests (report Fig. 1.7)</h2>", fig(p, "fig-1-7.png"),
                "<h2>2. Training database</h2>",
                f"<p>Dataset 2 of REV-scale increments (<code>hmodel data generate 2</code> with the "
                f"options below), {ds.n_rows:,} rows.</p>",
                _options_table(spec.to_dict(), DATASET_OPTIONS),
                "<h2>3. Surrogate accuracy on new rows</h2>", trained,
                "<p>Held-out rows of the database above.</p>", _table(metrics), fig(p, "parity.png"),
                "<h2>4. ANN-based H-model against the closed form</h2>",
                f"<p>{len(specs)} loading paths, {n_points} material points{several}. "
                f"<i>in the report (§3.1)</i>: yes for the paths the report compared itself "
                f"({', '.join(in_report)}), no for those it never tried ({', '.join(new_paths)}). "
                f"On the isotropic path Δq is relative to the peak mean stress (q stays at round-off). "
                f"Speed ratio: the closed form's time over the surrogate's; each row's <i>ran</i> says "
                f"on which path and threads. {html.escape(conditions)}</p>",
                f"<p>{html.escape(_speed_text(dev_rows))}</p>",
                _table(_comparison_rows(dev_rows), 3)]
        body += [fig(p, f"compare-{s.name}.png") for s in specs if f"compare-{s.name}.png" in figs]
        if t21:
            from .sweep import beside_report
            body += ["<h2>5. Table 2.1 beside the report's</h2>",
                     "<p>Model 1 (3 tanh layers of 8 nodes, 60k rows of Dataset 2, min-max) scored as the "
                     "report's Fig. 2.7, with the inputs as the model runs them (forces before the "
                     "increment) and as the report's published code feeds them (forces after it).</p>",
                     _table(beside_report(t21), 6), fig(p, "table-2-1.png"),
                     "<p>Every run (table-2-1.csv):</p>", _table(t21, 4)]
        body += ["<h2>Timings</h2>", _table(timings, 3)]
        style = "body{font-family:sans-serif;max-width:1200px;margin:auto}table{border-collapse:collapse}" \
                "td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px}figcaption{font-size:14px}" \
                ".file{color:#777}"
        p.write_text(f"<!doctype html><html><head><meta charset='utf-8'><title>hmodel report</title>"
                     f"<style>{style}</style></head><body>{''.join(body)}</body></html>")
    return write_html


def reproduce(out: Path, quick: bool, solver_spec: str = "surrogate",
              progress: Callable[[float], None] | None = None) -> Path:
    """Run the study into ``out`` (a fresh folder is written atomically); returns report.html."""
    from ..io import write_outputs, write_rows
    from ..surrogate.torch_support import require_torch

    plan = QUICK if quick else FULL
    if plan.train_rows:
        require_torch("reproduce without --quick (it trains a surrogate)")  # before any work
    work = out.with_name(out.name + ".work")
    work.mkdir(parents=True, exist_ok=True)
    study = _Study(plan, Params(n_theta=plan.n_theta), work, progress or (lambda f: None))

    _engine(study)
    ds, spec = _database(study)
    solver, solver_spec, metrics = _surrogate(study, ds, solver_spec)
    dev_rows, specs, conditions = _comparison(study, solver)
    t21 = _table21_step(study)
    study.files["timings.csv"] = lambda p: write_rows(study.timings, p)
    # last: it reads the figures written before it
    study.files["report.html"] = _report_writer(
        study, quick=quick, solver_spec=solver_spec, model=solver.model, ds=ds, spec=spec,
        metrics=metrics, dev_rows=dev_rows, specs=specs, conditions=conditions, t21=t21)
    write_outputs(out, study.files)
    shutil.rmtree(work, ignore_errors=True)
    study.tick(1.0)
    return out / "report.html"
