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
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

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


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode()
    return f'<figure><img src="data:image/png;base64,{data}" style="max-width:100%"><figcaption>{html.escape(path.name)}</figcaption></figure>'


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
    study.timed(f"Table 2.1 sweep ({len(t21)} trainings)", t)
    return t21


def _report_writer(study: _Study, *, quick: bool, solver_spec: str, model, ds, spec, metrics,
                   dev_rows, specs, conditions, t21):
    """The writer of ``report.html``: every step's tables and the figures written before it."""
    from ..surrogate.shipped import DEFAULT_TRAINING

    plan, files, timings = study.plan, study.files, study.timings

    def write_html(p: Path) -> None:
        figs = {name: p.parent / name for name in files if name.endswith(".png")}
        body = [f"<h1>hmodel {html.escape(__version__)}: the H-model and its neural surrogate</h1>",
                f"<p>{'Quick run' if quick else 'Full run'}; nθ = {plan.n_theta}, increments {plan.step:g} "
                f"(consolidation 1e-4); surrogate {html.escape(solver_spec)} "
                f"({html.escape(model.meta.get('formulation', {}).get('name', ''))}).</p>",
                "<h2>1. Drained biaxial tests (report Fig. 1.7)</h2>", _img(figs["fig-1-7.png"]),
                "<h2>2. Training database</h2>",
                f"<p>Dataset 2 of REV-scale increments, {ds.n_rows:,} rows; options: "
                f"{html.escape(str(spec.to_dict()))}</p>",
                "<h2>3. Surrogate accuracy on new rows</h2>",
                f"<p>{'Trained here: ' + html.escape(str(DEFAULT_TRAINING)) if plan.train_rows else 'The shipped model.'}"
                f" Held-out rows of the database above.</p>", _table(metrics), _img(figs["parity.png"]),
                "<h2>4. ANN-based H-model against the closed form</h2>",
                f"<p>{html.escape(conditions)} Speed ratio: closed form's time over the "
                f"surrogate's; each row's <i>ran</i> says on which path and threads.</p>",
                _table(dev_rows, 3)]
        body += [_img(figs[f"compare-{s.name}.png"]) for s in specs if f"compare-{s.name}.png" in figs]
        if t21:
            from .sweep import beside_report
            body += ["<h2>5. Table 2.1 beside the report's</h2>",
                     "<p>Model 1 (3 tanh layers of 8 nodes, 60k rows of Dataset 2, min-max) scored as the "
                     "report's Fig. 2.7, with the inputs as the model runs them (forces before the "
                     "increment) and as the report's published code feeds them (forces after it).</p>",
                     _table(beside_report(t21), 6), _img(figs["table-2-1.png"]),
                     "<p>Every run (table-2-1.csv):</p>", _table(t21, 4)]
        body += ["<h2>Timings</h2>", _table(timings, 3)]
        style = "body{font-family:sans-serif;max-width:1200px;margin:auto}table{border-collapse:collapse}" \
                "td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px}"
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
