"""``hmodel run iso | biaxial | strain-path | triaxial | true-triaxial | oedometer | program``:
material-point tests to result.csv + result.png (2D: iso, biaxial, strain-path; 3D: triaxial,
true-triaxial, oedometer; a program in either)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import read_strain_path, write_outputs, write_rows
from ..loading import (
    AXIAL_STEP,
    ISO_STEP,
    MAX_STRAIN_STEP,
    Program,
    ProgramFailed,
    run_biaxial,
    run_isotropic,
    run_oedometer,
    run_strain_path,
    run_triaxial,
    run_true_triaxial,
)
from ..loading.result import PathResult
from ..plotting import plot_contact_fabric, plot_result
from ..rev.contacts import fabric_rows
from ..solvers import get_solver, get_solver_3d
from ..units import parse_pressures
from .common3d import (
    AxialOpt,
    AzimuthsOpt,
    FabricOpt,
    IsoStepOpt,
    OrderOpt,
    Param3DOpt,
    RadialOpt,
    Solver3DOpt,
    StepOpt,
    setup_3d,
)
from .options import (
    CalibrationOpt,
    ContactFabricOpt,
    E0Opt,
    ERefOpt,
    FallbackOpt,
    GateOpt,
    ModelOpt,
    P0Opt,
    ParamOpt,
    SolverOpt,
    axial_strain as checked_axial_strain,
    material_points,
    out_folder,
    positive,
    specimen,
    strain_help,
)
from .progress import LazyProgress

app = typer.Typer(no_args_is_help=True, help="Run a loading path or a loading program at the material point.")

OutOpt = out_folder("Output folder (result.csv, result.png).")
ProgramSolverOpt = Annotated[str, typer.Option(
    "--solver", help="Cell solver: closed-form, surrogate (the shipped model), surrogate:MODEL_FILE or "
                     "dem:MESOSTRUCTURE (YADE cells). In a 3D program, the cell of the hexagons of every "
                     "bi-hexagon, as run triaxial's --solver (surrogate: the network trained with the "
                     "equilibrium sliding_rhs), or dem:bihexagon.")]


def _solver(spec: str, gate: float | None, fallback: str | None):
    """The cell solver of --solver, gated where --gate/--fallback say so."""
    if gate is None and fallback is None:
        return get_solver(spec)
    from ..surrogate.solver import gated_solver
    return gated_solver(spec, gate, fallback)


def _gate_line(solver, gate: float | None) -> None:
    """The summary line of a gated run (--gate given)."""
    if gate is not None:
        from ..surrogate.solver import gate_summary
        typer.echo(gate_summary(solver))


def _finish(result: PathResult, out: Path) -> None:
    writers = {"result.csv": result.to_csv, "result.png": lambda p: plot_result(result, p)}
    fabrics = result.meta.get("contact_fabric")
    if fabrics is not None:
        rows = fabric_rows([({"point": b, "state": state}, f) for state in ("consolidated", "final")
                            for b, f in enumerate(fabrics[state]) if f is not None])
        dim = 3 if "eps33" in result.columns else 2
        writers["contact_fabric.csv"] = lambda p: write_rows(rows, p)
        writers["contact_fabric.png"] = lambda p: plot_contact_fabric(
            rows, p, dim, f"contact fabric, {result.meta.get('test', '')} test")
    write_outputs(out, writers)
    typer.echo(f"wrote {out / 'result.csv'} ({len(result)} rows) and {out / 'result.png'}"
               + (" and contact_fabric.csv, .png" if fabrics is not None else ""))


@app.command("iso")
def iso(p0: P0Opt = "200kPa", param: ParamOpt = None, out: OutOpt = Path("results/iso"),
        iso_step: Annotated[float, typer.Option(help=strain_help("Strain increment of eps11 and eps22."))] = ISO_STEP,
        solver: SolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None, model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """Isotropic compression (equal strain increments) until p reaches p0."""
    pressures = parse_pressures(p0, "--p0")
    params = material_points(param, len(pressures), specimen(model, calibration, e0, e_ref, 2))
    with LazyProgress("isotropic compression") as progress:
        cells = _solver(solver, gate, fallback)
        result = run_isotropic(params, pressures, solver=cells,
                               step=positive(iso_step, "--iso-step"), progress=progress)
    _finish(result, out)
    _gate_line(cells, gate)


@app.command("biaxial")
def biaxial(p0: P0Opt = "200kPa",
            axial_strain: Annotated[float, typer.Option(help=strain_help("Axial strain after consolidation."))] = 0.1,
            undrained: Annotated[bool, typer.Option("--undrained", help="Isochoric (undrained) test.")] = False,
            param: ParamOpt = None, out: OutOpt = Path("results/biaxial"),
            step: Annotated[float, typer.Option(help=strain_help(
                "Axial strain increment (1e-4 here and in the 3D tests; calibrate's model runs at 1e-3)."))] = AXIAL_STEP,
            iso_step: Annotated[float, typer.Option(help=strain_help("Strain increment of the consolidation."))] = ISO_STEP,
            solver: SolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None, model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None,
        contact_fabric: ContactFabricOpt = False) -> None:
    """Isotropic consolidation to p0, then drained (sig22 = p0) or undrained biaxial compression."""
    pressures = parse_pressures(p0, "--p0")
    params = material_points(param, len(pressures), specimen(model, calibration, e0, e_ref, 2))
    checked_axial_strain(axial_strain)
    with LazyProgress("biaxial test") as progress:
        cells = _solver(solver, gate, fallback)
        result = run_biaxial(params, pressures, axial_strain, undrained=undrained, solver=cells,
                             iso_step=positive(iso_step, "--iso-step"),
                             step=positive(step, "--step"), progress=progress,
                             contact_fabric=contact_fabric)
    _finish(result, out)
    _gate_line(cells, gate)


@app.command("strain-path")
def strain_path(path: Annotated[Path, typer.Argument(help="CSV with header eps11,eps22[,eps12] of cumulative strains.")],
                param: ParamOpt = None, out: OutOpt = Path("results/strain-path"),
                max_step: Annotated[Optional[float], typer.Option(
                    help=strain_help(f"Split a row's increment into sub-steps no larger than this strain "
                                     f"(default: one increment per row; {MAX_STRAIN_STEP:g} is converged)."))] = None,
                solver: SolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None, model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """Follow a prescribed strain path; one result row per input row, in order."""
    params = material_points(param, 1, specimen(model, calibration, e0, e_ref, 2))
    eps = read_strain_path(path)
    if max_step is not None:
        positive(max_step, "--max-step")
    with LazyProgress("strain path") as progress:
        cells = _solver(solver, gate, fallback)
        result = run_strain_path(params, eps, solver=cells, max_step=max_step, progress=progress)
    _finish(result, out)
    _gate_line(cells, gate)


@app.command("program")
def program(path: Annotated[Path, typer.Argument(help="TOML file of stages (see docs/programs.md and examples/).")],
            param: ParamOpt = None, out: OutOpt = Path("results/program"),
            solver: ProgramSolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None,
            keep_partial: Annotated[bool, typer.Option(
                "--keep-partial", help="When an increment cannot be solved, still write every state "
                                       "computed before it (exit status 1 all the same).")] = False,
            model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """A loading program: stages of mixed stress/strain control, cycles, stopping criteria."""
    prog = Program.from_toml(path)
    spec = specimen(model, calibration, e0, e_ref, prog.dim)
    if prog.dim == 3 and (gate is not None or fallback is not None):
        raise InputError("--gate and --fallback gate a 2D learned cell: a 3D program's learned "
                         "bi-hexagon runs ungated, as run triaxial's")
    cells = get_solver_3d(solver) if prog.dim == 3 else None
    params = prog.with_params(param, None if spec is None else spec.base, cells)
    if spec is not None:
        if len(spec.e0) > 1:
            raise InputError("--e0 of a program is one void ratio (a program runs one material point)")
        params = spec.at_e0([params], 1)[0]
    with LazyProgress(f"program {prog.name}") as progress:
        try:
            result = prog.run(params, solver=cells if cells is not None else _solver(solver, gate, fallback),
                              progress=progress)
        except ProgramFailed as e:
            if keep_partial and len(e.result):
                _finish(e.result, out)
            raise
    _finish(result, out)
    for s in result.meta["stopped"]:
        where = f"stage {s['stage']!r}" + (f", cycle {s['cycle']}" if s["cycle"] else "")
        typer.echo(f"stopped {where}: " + (f"until {s['until']} met" if "until" in s else s["failure"]))
    for name, n in result.meta["cycles"].items():
        typer.echo(f"{name}: {n} cycle{'s' if n != 1 else ''}")


# ---------------------------------------------------------------------- 3D tests

def _steps_3d(sphere, cells, iso_step: float, step: float) -> dict:
    """The keywords every 3D lab test takes from its options."""
    return {"sphere": sphere, "solver": cells, "iso_step": positive(iso_step, "--iso-step"),
            "step": positive(step, "--step")}


@app.command("triaxial")
def triaxial(p0: P0Opt = "200kPa", axial_strain: AxialOpt = 0.1,
             undrained: Annotated[bool, typer.Option("--undrained", help="Undrained: eps_v = 0, eps22 = eps33.")] = False,
             extension: Annotated[bool, typer.Option(
                 "--extension", help="Axial unloading at constant radial stress (sig11 < sig22 = sig33).")] = False,
             radial: RadialOpt = None,
             param: Param3DOpt = None, order: OrderOpt = None, azimuths: AzimuthsOpt = None,
             fabric: FabricOpt = 0.0, out: OutOpt = Path("results/triaxial"), step: StepOpt = AXIAL_STEP,
             iso_step: IsoStepOpt = ISO_STEP, solver: Solver3DOpt = "closed-form",
             model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None,
             contact_fabric: ContactFabricOpt = False) -> None:
    """The 3D H-model's triaxial test: isotropic consolidation to p0, then drained (sig22 = sig33
    = p0, or with --radial equal one radial strain) or undrained axial compression, or
    extension, along axis 1."""
    spec = specimen(model, calibration, e0, e_ref, 3)
    pressures, params, sphere, cells = setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                 solver, spec)
    if radial is None and spec is not None:
        radial = spec.radial
    with LazyProgress("triaxial test") as progress:
        result = run_triaxial(params, pressures, axial_strain, undrained=undrained, extension=extension,
                              radial=radial, progress=progress, contact_fabric=contact_fabric,
                              **_steps_3d(sphere, cells, iso_step, step))
    _finish(result, out)


@app.command("true-triaxial")
def true_triaxial(p0: P0Opt = "200kPa",
                  b: Annotated[float, typer.Option(
                      "--b", min=0.0, max=1.0,
                      help="b = (s2 - s3)/(s1 - s3) in [0, 1], held with p (0: triaxial compression, "
                           "1: extension); Lode angle atan(sqrt(3) b/(2 - b)).")] = 0.5,
                  axial_strain: AxialOpt = 0.1, param: Param3DOpt = None, order: OrderOpt = None,
                  azimuths: AzimuthsOpt = None, fabric: FabricOpt = 0.0,
                  out: OutOpt = Path("results/true-triaxial"), step: StepOpt = AXIAL_STEP,
                  iso_step: IsoStepOpt = ISO_STEP, solver: Solver3DOpt = "closed-form",
                  model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None,
                  contact_fabric: ContactFabricOpt = False) -> None:
    """Drained true triaxial test at constant p = p0 and constant b: isotropic consolidation,
    then compression along axis 1 (the major principal stress)."""
    pressures, params, sphere, cells = setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                 solver, specimen(model, calibration, e0, e_ref, 3))
    with LazyProgress("true triaxial test") as progress:
        result = run_true_triaxial(params, pressures, b, axial_strain, progress=progress,
                                   contact_fabric=contact_fabric, **_steps_3d(sphere, cells, iso_step, step))
    _finish(result, out)


@app.command("oedometer")
def oedometer(p0: P0Opt = "200kPa", axial_strain: AxialOpt = 0.05, param: Param3DOpt = None,
              order: OrderOpt = None, azimuths: AzimuthsOpt = None, fabric: FabricOpt = 0.0,
              out: OutOpt = Path("results/oedometer"), step: StepOpt = AXIAL_STEP,
              iso_step: IsoStepOpt = ISO_STEP, solver: Solver3DOpt = "closed-form",
              model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None,
              contact_fabric: ContactFabricOpt = False) -> None:
    """Oedometric compression of the 3D H-model (eps22 = eps33 = 0) from isotropic consolidation
    to p0; K0 = sig_r/sig_a at its end is printed and is the column K0 of result.csv."""
    pressures, params, sphere, cells = setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                 solver, specimen(model, calibration, e0, e_ref, 3))
    with LazyProgress("oedometric test") as progress:
        result = run_oedometer(params, pressures, axial_strain, progress=progress,
                               contact_fabric=contact_fabric, **_steps_3d(sphere, cells, iso_step, step))
    _finish(result, out)
    p0s = result.meta["p0"]
    for k, k0 in enumerate(result.meta["K0"]):
        where = f"p0 = {p0s[k if len(p0s) > 1 else 0] / 1e3:g} kPa" + (f", point {k}" if len(p0s) == 1 and
                                                                           len(result.meta["K0"]) > 1 else "")
        typer.echo(f"K0 = sig_r/sig_a after {axial_strain:g} axial strain ({where}): {k0:.4f}")
