"""``hmodel run iso | biaxial | strain-path | triaxial | true-triaxial | oedometer | program``:
material-point tests to result.csv + result.png (2D: iso, biaxial, strain-path; 3D: triaxial,
true-triaxial, oedometer; a program in either)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..calibrate.calibrated import Specimen
from ..errors import InputError
from ..io import read_strain_path, write_outputs
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
from ..loading.lab_tests import check_3d_params
from ..loading.result import PathResult
from ..params import UNITS, Params, parse_point_assignments
from ..plotting import plot_result
from ..rev.sphere import Sphere
from ..solvers import get_solver
from ..units import parse_pressures
from .options import CalibrationOpt, E0Opt, ERefOpt, ModelOpt, out_folder, specimen
from .progress import LazyProgress

app = typer.Typer(no_args_is_help=True, help="Run a loading path or a loading program at the material point.")

ParamOpt = Annotated[Optional[list[str]], typer.Option(
    "--param", "-p", metavar="NAME=VALUE",
    help="Model parameter, repeatable; angles in degrees. A comma list (phi_g=25,35) gives one "
         "material point per value, broadcast against --p0 (n_theta, radius, volume are shared). "
         "Names: " + ", ".join(
        f"{k} [{u}]" for k, u in UNITS.items()))]
OutOpt = out_folder("Output folder (result.csv, result.png).")
SolverOpt = Annotated[str, typer.Option("--solver", help="Cell solver: closed-form, surrogate (the shipped model), surrogate:MODEL_FILE or "
                                                        "dem:MESOSTRUCTURE (YADE cells: dem:standard, dem:hexagon-center, "
                                                        "dem:hexagon-unequal).")]
P0Opt = Annotated[str, typer.Option("--p0", help="Confining pressure(s): 200kPa, 0.2MPa, 2e5 or a "
                                                  "comma list 100kPa,200kPa,400kPa.")]


GateOpt = Annotated[Optional[float], typer.Option(
    "--gate", help="Quantile level of a learned solver's trust score (e.g. 0.99) above which a cell "
                   "increment goes to --fallback; needs a model with a trust reference "
                   "('hmodel surrogate trust').")]
FallbackOpt = Annotated[Optional[str], typer.Option(
    "--fallback", help="Exact cell solver for the cells above --gate: closed-form (H-cell networks), or "
                       "a richer cell's DEM cell dem:MESO (its meso network; each cell carries its DEM state).")]


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
    write_outputs(out, {"result.csv": result.to_csv, "result.png": lambda p: plot_result(result, p)})
    typer.echo(f"wrote {out / 'result.csv'} ({len(result)} rows) and {out / 'result.png'}")


def _positive(value: float, name: str) -> float:
    if not value > 0 or value != value or value == float("inf"):
        raise InputError(f"{name} must be a positive finite number, got {value}")
    return value


def _material_points(param: list[str] | None, n_pressures: int, model: "Specimen | None" = None) -> Params | list[Params]:
    """``--param`` with comma lists: one parameter set per material point, broadcast against the
    ``--p0`` list (equal lengths, or one of them 1); on the parameters of ``model`` (a
    calibration's, and each point's e0) where given."""
    sets = parse_point_assignments(param, None if model is None else model.base)
    if len(sets) > 1 and n_pressures > 1 and len(sets) != n_pressures:
        raise InputError(f"--param lists give {len(sets)} material points and --p0 gives "
                         f"{n_pressures}: give equal lengths, or one value")
    if model is not None:
        sets = model.at_e0(sets, n_pressures)
    return sets[0] if len(sets) == 1 else sets


@app.command("iso")
def iso(p0: P0Opt = "200kPa", param: ParamOpt = None, out: OutOpt = Path("results/iso"),
        iso_step: Annotated[float, typer.Option(help="Strain increment of eps11 and eps22.")] = ISO_STEP,
        solver: SolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None, model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """Isotropic compression (equal strain increments) until p reaches p0."""
    pressures = parse_pressures(p0)
    params = _material_points(param, len(pressures), specimen(model, calibration, e0, e_ref, 2))
    with LazyProgress("isotropic compression") as progress:
        cells = _solver(solver, gate, fallback)
        result = run_isotropic(params, pressures, solver=cells,
                               step=_positive(iso_step, "--iso-step"), progress=progress)
    _finish(result, out)
    _gate_line(cells, gate)


@app.command("biaxial")
def biaxial(p0: P0Opt = "200kPa",
            axial_strain: Annotated[float, typer.Option(help="Axial strain after consolidation.")] = 0.1,
            undrained: Annotated[bool, typer.Option("--undrained", help="Isochoric (undrained) test.")] = False,
            param: ParamOpt = None, out: OutOpt = Path("results/biaxial"),
            step: Annotated[float, typer.Option(help="Axial strain increment.")] = AXIAL_STEP,
            iso_step: Annotated[float, typer.Option(help="Strain increment of the consolidation.")] = ISO_STEP,
            solver: SolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None, model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """Isotropic consolidation to p0, then drained (sig22 = p0) or undrained biaxial compression."""
    pressures = parse_pressures(p0)
    params = _material_points(param, len(pressures), specimen(model, calibration, e0, e_ref, 2))
    _positive(axial_strain, "--axial-strain")
    if axial_strain >= 1:
        raise InputError(f"--axial-strain must be below 1, got {axial_strain}")
    with LazyProgress("biaxial test") as progress:
        cells = _solver(solver, gate, fallback)
        result = run_biaxial(params, pressures, axial_strain, undrained=undrained, solver=cells,
                             iso_step=_positive(iso_step, "--iso-step"),
                             step=_positive(step, "--step"), progress=progress)
    _finish(result, out)
    _gate_line(cells, gate)


@app.command("strain-path")
def strain_path(path: Annotated[Path, typer.Argument(help="CSV with header eps11,eps22[,eps12] of cumulative strains.")],
                param: ParamOpt = None, out: OutOpt = Path("results/strain-path"),
                max_step: Annotated[Optional[float], typer.Option(
                    help=f"Split a row's increment into sub-steps no larger than this strain "
                         f"(default: one increment per row; {MAX_STRAIN_STEP:g} is converged).")] = None,
                solver: SolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None, model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """Follow a prescribed strain path; one result row per input row, in order."""
    params = _material_points(param, 1, specimen(model, calibration, e0, e_ref, 2))
    eps = read_strain_path(path)
    if max_step is not None:
        _positive(max_step, "--max-step")
    with LazyProgress("strain path") as progress:
        cells = _solver(solver, gate, fallback)
        result = run_strain_path(params, eps, solver=cells, max_step=max_step, progress=progress)
    _finish(result, out)
    _gate_line(cells, gate)


@app.command("program")
def program(path: Annotated[Path, typer.Argument(help="TOML file of stages (see docs/programs.md and examples/).")],
            param: ParamOpt = None, out: OutOpt = Path("results/program"),
            solver: SolverOpt = "closed-form", gate: GateOpt = None,
        fallback: FallbackOpt = None,
            keep_partial: Annotated[bool, typer.Option(
                "--keep-partial", help="When an increment cannot be solved, still write every state "
                                       "computed before it (exit status 1 all the same).")] = False,
            model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """A loading program: stages of mixed stress/strain control, cycles, stopping criteria."""
    prog = Program.from_toml(path)
    spec = specimen(model, calibration, e0, e_ref, 2 if prog.sphere is None else 3)
    params = prog.with_params(param, None if spec is None else spec.base)
    if spec is not None:
        if len(spec.e0) > 1:
            raise InputError("--e0 of a program is one void ratio (a program runs one material point)")
        params = spec.at_e0([params], 1)[0]
    with LazyProgress(f"program {prog.name}") as progress:
        try:
            result = prog.run(params, solver=_solver(solver, gate, fallback), progress=progress)
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

Param3DOpt = Annotated[Optional[list[str]], typer.Option(
    "--param", "-p", metavar="NAME=VALUE",
    help="Model parameter, repeatable; angles in degrees. A comma list (phi_g=25,35) gives one "
         "material point per value, broadcast against --p0. In 3D: kn, kt_kn, phi_g, alpha0, "
         "radius, volume (hexagon, rectangle, box), g2, sliding_rhs (default here: equilibrium); "
         "the directions and fabric are --order, --azimuths, --fabric.")]
OrderOpt = Annotated[Optional[int], typer.Option(
    "--order", help=f"Order of the Lebedev rule of the directions (default: Sphere's, "
                    f"{Sphere.__dataclass_fields__['order'].default}; one of 3, 5, 7, 9, 11, 15, 17, 19, "
                    f"21, 23, 29, 31, 35, 41, ...).")]
AzimuthsOpt = Annotated[Optional[int], typer.Option(
    "--azimuths", min=1, help=f"Bi-hexagons per direction, turned about it (default: Sphere's, "
                              f"{Sphere.__dataclass_fields__['n_azimuth'].default}).")]
FabricOpt = Annotated[float, typer.Option(
    "--fabric", min=-1.0, max=1.0, help="Fabric intensity alpha_omega in [-1, 1] of the directions' density "
                     "1 + alpha_omega cos 2psi about the axial axis 1 (the deposition axis).")]
AxialOpt = Annotated[float, typer.Option(help="Axial strain after consolidation (its magnitude).")]
StepOpt = Annotated[float, typer.Option(help="Axial strain increment.")]
IsoStepOpt = Annotated[float, typer.Option(help="Strain increment of the consolidation.")]


def _sphere(order: int | None, azimuths: int | None, fabric: float) -> Sphere:
    """The 3D discretization of --order, --azimuths, --fabric (deposition axis: axis 1)."""
    kw = {k: v for k, v in (("order", order), ("n_azimuth", azimuths)) if v is not None}
    return Sphere(**kw, alpha_omega=fabric, axis=(1.0, 0.0, 0.0))


Solver3DOpt = Annotated[str, typer.Option(
    "--solver", help="Cell solver of the hexagons of every bi-hexagon: closed-form (compiled), or a "
                     "surrogate of the 2D H-cell, surrogate[:MODEL] (the learned 3D cell, on the "
                     "generic driver; plain 'surrogate' is the shipped network trained with the equilibrium "
                     "sliding_rhs; sliding_rhs defaults to the one the model was trained with); "
                     "or dem:bihexagon[:K=V,...], the bi-hexagon of spheres in YADE (slow).")]


def _solver_3d(spec: str):
    """The 3D cell of --solver: the closed-form bi-hexagon, a 3D cell solver (``dem:bihexagon``),
    or a bi-hexagon whose hexagons a 2D H-cell solver steps (refused in one line for richer or
    DEM cells: check_hexagon)."""
    from ..cell.bihex import BiHexSolver

    if spec == "surrogate":
        # The 3D model runs with the equilibrium λ (with the report's the 3D REV stops near 1 %
        # strain, docs/model3d.md), so its shipped learned cell is the network trained with it.
        spec = "surrogate:equilibrium"
    solver = get_solver(spec)
    if spec == "closed-form":
        return BiHexSolver()
    return solver if solver.n_lengths == 3 else BiHexSolver(hexagon=solver)


def _points_3d(param: list[str] | None, n_pressures: int, solver=None,
               model: Specimen | None = None) -> Params | list[Params]:
    """``--param`` of a 3D test (:func:`_material_points`): the 2D model's own parameters are
    refused, naming their 3D equivalent; ``sliding_rhs`` defaults to ``equilibrium`` (with the
    report's λ the mixed-control driver cannot yet pass the jumps of the 3D cells' events), or
    for a learned hexagon to the one its model was trained with (a surrogate refuses others);
    a calibrated ``model`` keeps its own."""
    names = [item.partition("=")[0].strip() for item in param or []]
    check_3d_params(names)
    if "sliding_rhs" not in names and (model is None or model.base is None):
        rhs = "equilibrium"
        f = getattr(getattr(solver, "hexagon", None), "formulation", None)
        if f is not None:
            rhs = (f.to_dict().get("params") or {}).get("sliding_rhs", rhs)
        param = [f"sliding_rhs={rhs}", *(param or [])]
    return _material_points(param, n_pressures, model)


def _axial(axial_strain: float) -> float:
    _positive(axial_strain, "--axial-strain")
    if axial_strain >= 1:
        raise InputError(f"--axial-strain must be below 1, got {axial_strain}")
    return axial_strain


def _setup_3d(p0, param, axial_strain, order, azimuths, fabric, solver, model: Specimen | None = None):
    """What every 3D test reads from its options, checked before any work: the pressures, the
    material points' parameters, the sphere (a calibration's, changed by the options given) and
    the cell solver."""
    pressures = parse_pressures(p0)
    cells = _solver_3d(solver)
    params = _points_3d(param, len(pressures), cells, model)
    _axial(axial_strain)
    sphere = _sphere(order, azimuths, fabric)
    if model is not None and model.sphere is not None:
        given = {k: v for k, v in (("order", order), ("n_azimuth", azimuths)) if v is not None}
        sphere = replace(model.sphere, **given, **({"alpha_omega": fabric} if fabric else {}))
    return pressures, params, sphere, cells


def _steps_3d(sphere, cells, iso_step: float, step: float) -> dict:
    """The keywords every 3D lab test takes from its options."""
    return {"sphere": sphere, "solver": cells, "iso_step": _positive(iso_step, "--iso-step"),
            "step": _positive(step, "--step")}


@app.command("triaxial")
def triaxial(p0: P0Opt = "200kPa", axial_strain: AxialOpt = 0.1,
             undrained: Annotated[bool, typer.Option("--undrained", help="Undrained: eps_v = 0, eps22 = eps33.")] = False,
             extension: Annotated[bool, typer.Option(
                 "--extension", help="Axial unloading at constant radial stress (sig11 < sig22 = sig33).")] = False,
             param: Param3DOpt = None, order: OrderOpt = None, azimuths: AzimuthsOpt = None,
             fabric: FabricOpt = 0.0, out: OutOpt = Path("results/triaxial"), step: StepOpt = AXIAL_STEP,
             iso_step: IsoStepOpt = ISO_STEP, solver: Solver3DOpt = "closed-form",
             model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """The 3D H-model's triaxial test: isotropic consolidation to p0, then drained (sig22 = sig33
    = p0) or undrained axial compression, or extension, along axis 1."""
    pressures, params, sphere, cells = _setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                 solver, specimen(model, calibration, e0, e_ref, 3))
    with LazyProgress("triaxial test") as progress:
        result = run_triaxial(params, pressures, axial_strain, undrained=undrained, extension=extension,
                              progress=progress, **_steps_3d(sphere, cells, iso_step, step))
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
                  model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """Drained true triaxial test at constant p = p0 and constant b: isotropic consolidation,
    then compression along axis 1 (the major principal stress)."""
    pressures, params, sphere, cells = _setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                 solver, specimen(model, calibration, e0, e_ref, 3))
    with LazyProgress("true triaxial test") as progress:
        result = run_true_triaxial(params, pressures, b, axial_strain, progress=progress,
                                   **_steps_3d(sphere, cells, iso_step, step))
    _finish(result, out)


@app.command("oedometer")
def oedometer(p0: P0Opt = "200kPa", axial_strain: AxialOpt = 0.05, param: Param3DOpt = None,
              order: OrderOpt = None, azimuths: AzimuthsOpt = None, fabric: FabricOpt = 0.0,
              out: OutOpt = Path("results/oedometer"), step: StepOpt = AXIAL_STEP,
              iso_step: IsoStepOpt = ISO_STEP, solver: Solver3DOpt = "closed-form",
              model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None) -> None:
    """Oedometric compression of the 3D H-model (eps22 = eps33 = 0) from isotropic consolidation
    to p0; K0 = sig_r/sig_a at its end is printed and is the column K0 of result.csv."""
    pressures, params, sphere, cells = _setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                 solver, specimen(model, calibration, e0, e_ref, 3))
    with LazyProgress("oedometric test") as progress:
        result = run_oedometer(params, pressures, axial_strain, progress=progress,
                               **_steps_3d(sphere, cells, iso_step, step))
    _finish(result, out)
    p0s = result.meta["p0"]
    for k, k0 in enumerate(result.meta["K0"]):
        where = f"p0 = {p0s[k if len(p0s) > 1 else 0] / 1e3:g} kPa" + (f", point {k}" if len(p0s) == 1 and
                                                                           len(result.meta["K0"]) > 1 else "")
        typer.echo(f"K0 = sig_r/sig_a after {axial_strain:g} axial strain ({where}): {k0:.4f}")
