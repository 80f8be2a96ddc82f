"""``hmodel data generate | sample | info``: the H-cell databases of report §2.3."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs
from ..params import Params
from .options import ParamOpt, out_folder, strain_help, workers_opt
from .progress import LazyProgress

app = typer.Typer(no_args_is_help=True, help="Generate, sample and inspect H-cell databases.")

def _alpha0_range(text: str) -> tuple[float, float, float]:
    parts = text.split(":")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"--alpha0 expects MIN:MAX:STEP in degrees, got {text!r}") from None
    if len(values) == 1:
        values = [values[0], values[0], 1.0]
    if len(values) != 3:
        raise InputError(f"--alpha0 expects MIN:MAX:STEP in degrees, got {text!r}")
    return values[0], values[1], values[2]


def _theta_range(text: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(f"--theta expects MIN:MAX in degrees, got {text!r}") from None
    return lo, hi


def _solver(solver: str, mesostructure: str | None) -> str:
    """The spec of the cells a database is made of, as the registry resolves ``--solver`` (and
    ``--mesostructure`` after it): a bare word as its solver records it (``dem`` is
    ``dem:standard``), a spec with options as given, so that a manifest keeps its command's
    spelling."""
    from ..solvers import get_solver

    cell = get_solver(solver)
    if mesostructure is not None:
        # the mesostructure is the first option of a grain cell's spec: after a bare word only
        if cell.geometry is None or ":" in solver:
            raise InputError("--mesostructure needs --solver dem")
        solver = f"{solver}:{mesostructure}"
        cell = get_solver(solver)
    if cell.learned:  # rows are a database's to learn from: a network's answers are not
        raise InputError(f"--solver must be an exact cell solver (closed-form or dem), got the learned {solver!r}")
    return solver if ":" in solver else cell.name


@app.command("generate")
def generate(
    dataset: Annotated[int, typer.Argument(help="1: monotonic paths from the initial state; "
                                                "2: increments from their states; 3: increments from "
                                                "the states of a REV's cells (--rev-paths).")],
    out: out_folder("Dataset folder (Parquet shards + manifest.json)."),
    directions: Annotated[Optional[int], typer.Option(help="Path directions theta over the --theta range, inclusive "
                                                           "(default 91; --dim 3: 12).")] = None,
    theta: Annotated[Optional[str], typer.Option(help="Range MIN:MAX [deg] of the path directions in the (eps1, eps2) "
                                                      "plane; 0:360 adds paths in extension (default 0:90; --dim 3: "
                                                      "-60:150, eps2 split between l2 and l3).")] = None,
    alpha0: Annotated[Optional[str], typer.Option(help="Initial opening angles MIN:MAX:STEP [deg] "
                                                       "(default 32:88:2; --dim 3: 40:60:10).")] = None,
    max_strain: Annotated[Optional[float], typer.Option(help=strain_help("Total cell strain of a path (default 0.3; "
                                                                         "--dim 3: 0.1)."))] = None,
    step: Annotated[float, typer.Option(help=strain_help("Strain step of a path (recorded in Dataset 1)."))] = 0.001,
    start_every: Annotated[Optional[float], typer.Option(help="Dataset 2: strain between start states "
                                                              "(default 0.01; --dim 3: 0.005).")] = None,
    from_unloaded: Annotated[bool, typer.Option("--from-unloaded", help="Dataset 2: increments from the unloaded cell too.")] = False,
    prestrain: Annotated[float, typer.Option(help="Isotropic cell strain applied before every path, as a REV's consolidation.")] = 0.0,
    rev_paths: Annotated[str, typer.Option(help="Dataset 3: the REV's loading paths, drained:P0 or undrained:P0 [Pa], "
                                                "comma-separated; --directions cells, sheared in axial steps of "
                                                "--step to --max-strain.")] = "",
    magnitude: Annotated[Optional[float], typer.Option(help="Dataset 2: strain magnitude of an increment "
                                                            "(default 0.01; --dim 3: 0.002).")] = None,
    magnitude_min: Annotated[Optional[float], typer.Option(help="Dataset 2: spread the magnitudes over "
                                                                "[MIN, --magnitude] (default: all equal; --dim 3: 0).")] = None,
    increments: Annotated[Optional[int], typer.Option(help="Dataset 2: increment directions over [0, 360) deg "
                                                           "(default 168; --dim 3: 26 on the sphere).")] = None,
    substeps: Annotated[Optional[int], typer.Option(help="Dataset 2: equal sub-steps of an increment "
                                                         "(default 10; --dim 3: 1).")] = None,
    shard_rows: Annotated[int, typer.Option(help="Rows per shard, about.")] = 250_000,
    param: ParamOpt = None,
    workers: workers_opt("Local worker processes (default and most: one per CPU).", optional=True) = None,
    scheduler: Annotated[Optional[str], typer.Option(help="Dask scheduler address, e.g. tcp://host:8786.")] = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a dataset made with other options.")] = False,
    solver: Annotated[str, typer.Option(help="Cell solver: closed-form or dem (YADE cells, see --mesostructure).")] = "closed-form",
    mesostructure: Annotated[Optional[str], typer.Option(help="With --solver dem: standard (default), hexagon-center "
                                                              "or hexagon-unequal, with options after a colon: ratio=R and DEM settings such as tol=1e-7,max_iter=100000.")] = None,
    dim: Annotated[int, typer.Option("--dim", help="2: H-cell rows; 3: bi-hexagon rows of the 3D H-model "
                                                   "(dataset 2, closed form; small defaults).")] = 2,
    kt_kn: Annotated[str, typer.Option("--kt-kn", help="Datasets 1, 2: a material per path, kt/kn drawn "
                                                       "uniformly in LO:HI (e.g. 0.2:1; rows record it).")] = "",
    phi_g: Annotated[str, typer.Option("--phi-g", help="Datasets 1, 2: a material per path, phi_g drawn "
                                                       "uniformly in LO:HI [deg] (e.g. 10:45).")] = "",
    material_seed: Annotated[int, typer.Option(help="Seed of the per-path material draws (with the path id).")] = 0,
) -> None:
    """Compute a database into --out; re-running the same command resumes an interrupted run."""
    from ..data import DatasetSpec
    from ..data import generate as run
    from ..data.kinds import option_defaults

    defaults = option_defaults(dim)  # refuses a dimension no kind of rows has
    if dim == 3 and rev_paths:
        raise InputError("--rev-paths (dataset 3, a 2D REV's cells) is a 2D option; --dim 3 writes dataset 2")
    given = {"n_directions": directions, "theta": theta, "alpha0": alpha0, "max_strain": max_strain,
             "start_every": start_every, "magnitude": magnitude, "magnitude_min": magnitude_min,
             "n_increments": increments, "substeps": substeps}
    o = {k: defaults[k] if v is None else v for k, v in given.items()}
    directions, theta, alpha0, max_strain, start_every = (o[k] for k in ("n_directions", "theta", "alpha0",
                                                                         "max_strain", "start_every"))
    magnitude, magnitude_min, increments, substeps = (o[k] for k in ("magnitude", "magnitude_min",
                                                                     "n_increments", "substeps"))

    a_min, a_max, a_step = _alpha0_range(alpha0)
    t_min, t_max = _theta_range(theta)
    spec = DatasetSpec(kind=dataset, n_directions=directions, theta_min=t_min, theta_max=t_max, alpha0_min=a_min, alpha0_max=a_max,
                       alpha0_step=a_step, max_strain=max_strain, step=step, start_every=start_every, from_unloaded=from_unloaded,
                       prestrain=prestrain, rev_paths=rev_paths,
                       magnitude=magnitude, magnitude_min=magnitude_min, n_increments=increments, substeps=substeps,
                       shard_rows=shard_rows, solver=_solver(solver, mesostructure), dim=dim,
                       kt_kn_range=kt_kn, phi_g_range=phi_g, material_seed=material_seed)
    params = Params.parse_assignments(param)
    what = spec.dataset_kind.label
    with LazyProgress(f"{what}: {spec.n_rows:,} rows") as progress:
        ds = run(spec, params, out, workers=workers or os.cpu_count() or 1, scheduler=scheduler,
                 progress=progress, overwrite=overwrite)
    typer.echo(f"{what}: {ds.n_rows:,} rows in {len(ds.shards())} shards, {out}")


@app.command("sample")
def sample(
    source: Annotated[Path, typer.Argument(help="Dataset folder.")],
    out: out_folder("Folder for train.parquet, test.parquet, manifest.json."),
    train: Annotated[int, typer.Option(help="Rows of the training subset.")] = 60_000,
    test: Annotated[int, typer.Option(help="Rows of the test subset.")] = 10_000,
    method: Annotated[str, typer.Option(help="random, grid or lhs (Latin hypercube).")] = "random",
    seed: Annotated[int, typer.Option(help="Seed of every random choice.")] = 0,
    rules: Annotated[Optional[str], typer.Option(help="Cleaning rules, comma-separated, or none "
                                                       "(default: short,non-finite).")] = None,
    columns: Annotated[Optional[str], typer.Option(help="Columns spanning the sampled space "
                                                         "(default: the report's 8 inputs).")] = None,
) -> None:
    """Draw disjoint train/test subsets of the cleaned rows, reproducibly from --seed."""
    from ..data import Dataset
    from ..data.filters import parse_rules
    from ..data.sampling import INPUTS, write_split

    ds = Dataset.open(source)
    cols = tuple(c.strip() for c in columns.split(",")) if columns else INPUTS
    with LazyProgress(f"sampling ({method})") as progress:
        meta = write_split(ds, out, train, test, method, seed, parse_rules(rules), cols, progress)
    typer.echo(f"{meta['files']['train']['rows']:,} train and {meta['files']['test']['rows']:,} test "
               f"rows ({method}, seed {seed}) in {out}")


@app.command("info")
def info(
    source: Annotated[Path, typer.Argument(help="Dataset folder.")],
    rules: Annotated[Optional[str], typer.Option(help="Cleaning rules to count, comma-separated "
                                                       "(default: all).")] = None,
    out: out_folder("Folder for cleaning.csv and the figures (default: SOURCE/info).", optional=True) = None,
) -> None:
    """Rows, options, rows removed by each cleaning rule; report Figs. 2.1 and 2.2."""
    from rich.console import Console
    from rich.table import Table

    from ..data import Dataset
    from ..data.figures import plot_removed, plot_strain_distribution
    from ..data.filters import RULES, parse_rules, rule_counts

    ds = Dataset.open(source)
    names = parse_rules(rules) if rules else tuple(RULES)
    with LazyProgress("counting removed rows") as progress:
        counts = rule_counts(ds, names, progress)
    table = Table(title=f"{source}: dataset {ds.manifest['kind']}, {ds.n_rows:,} rows, "
                        f"{len(ds.shards())} shards")
    for c in ("rule", "removes", "rows removed", "fraction"):
        table.add_column(c)
    for name in names:
        table.add_row(name, RULES[name].description, f"{counts[name]:,}", f"{counts[name] / ds.n_rows:.2%}")
    table.add_row("any", "", f"{counts['total']:,}", f"{counts['total'] / ds.n_rows:.2%}")
    Console().print(table)

    def write_csv(path: Path) -> None:
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["rule", "description", "rows_removed", "rows", "fraction"])
            for name in names:
                w.writerow([name, RULES[name].description, counts[name], ds.n_rows, counts[name] / ds.n_rows])
            w.writerow(["any", "", counts["total"], ds.n_rows, counts["total"] / ds.n_rows])

    folder = out or Path(source) / "info"
    write_outputs(folder, {"cleaning.csv": write_csv,
                           "fig-2-1-strains.png": lambda p: plot_strain_distribution(ds, p),
                           "fig-2-2-removed.png": lambda p: plot_removed(ds, names, counts, p)})
    typer.echo(f"wrote {folder / 'cleaning.csv'}, {folder / 'fig-2-1-strains.png'}, "
               f"{folder / 'fig-2-2-removed.png'}")


@app.command("lab")
def lab(
    file: Annotated[str, typer.Argument(help="A laboratory file: one material's file of the Sand Triaxial Test "
                                             "Database (example:kfs is shipped), or a plain CSV whose headers "
                                             "carry units (eps_a[%], q[kPa], eps_v[%], sigma_r[kPa], ...).")],
    test: Annotated[Optional[list[str]], typer.Option("--test", "-t", help="A test id of the database file "
                                                                         "(repeatable; default: all).")] = None,
    kind: Annotated[Optional[str], typer.Option(help="The kind of a plain CSV's test (e.g. triaxial-drained).")] = None,
    p0: Annotated[Optional[str], typer.Option(help="The consolidation pressure of a plain CSV's test, with its "
                                                   "unit (e.g. 100kPa).")] = None,
    out: out_folder("Folder for tests.csv, one hmodel test file per test (eps_a,q,eps_v in fractions "
                    "and Pa) and ATTRIBUTION.txt.", optional=True) = None,
) -> None:
    """Read laboratory tests into hmodel's units (Pa, strains as fractions, compression positive)."""
    from rich.console import Console
    from rich.table import Table

    from ..calibrate.data import read_lab_tests
    from ..calibrate.lab import summary_rows, write_test_csv
    from ..units import parse_pressure

    tests, attribution = read_lab_tests(file, test, kind, parse_pressure(p0, "--p0") if p0 is not None else None)
    rows = summary_rows(tests)
    table = Table(title=f"{file}: {len(tests)} test(s), in hmodel's units")
    for c in ("test", "kind", "p0 [kPa]", "e0", "rows", "eps_a end", "peak q [kPa]", "eps_v end"):
        table.add_column(c)
    for r in rows:
        table.add_row(r["test"].split("#")[-1], r["kind"], f"{r['p0_kPa']:.1f}", f"{r['e0']}", f"{r['rows']}",
                      f"{r['eps_a_end']:.4g}", f"{r['q_peak_kPa']:.1f}",
                      "" if r["eps_v_end"] == "" else f"{r['eps_v_end']:.4g}")
    Console().print(table)
    if attribution:
        typer.echo(attribution)
    if out is None:
        return

    def write_table(path: Path) -> None:
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)

    writers = {"tests.csv": write_table}
    for t in tests:
        writers[t.name.split("#")[-1] + ".csv"] = lambda p, t=t: write_test_csv(t, p)
    if attribution:
        writers["ATTRIBUTION.txt"] = lambda p: p.write_text(attribution + "\n")
    write_outputs(out, writers)
    typer.echo(f"wrote {len(tests)} test file(s) and tests.csv in {out}")
