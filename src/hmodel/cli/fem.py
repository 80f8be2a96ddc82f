"""``hmodel fem biaxial | footing``: boundary-value problems with the H-model at every Gauss point."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError, SolverError
from ..params import Params
from ..solvers import get_solver
from ..units import parse_pressure
from .options import (
    CalibrationOpt,
    E0Opt,
    ERefOpt,
    ModelOpt,
    ParamOpt,
    SolverOpt,
    out_folder,
    specimen,
    strain_help,
)
from .progress import LazyProgress

app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="Finite elements (plane strain) with an H-model material point at every Gauss point.")

MeshOpt = Annotated[str, typer.Option(help="Elements NXxNY, e.g. 8x16.")]
ElementOpt = Annotated[str, typer.Option(help="q4 (2x2 Gauss points), q4b (q4 with the B-bar volumetric "
                                              "strain: each element's mean dilatation), q8 (serendipity, "
                                              "3x3) or t6 (quadratic triangles, 3 points).")]
StepsOpt = Annotated[int, typer.Option("--steps", help="Nominal load steps (a failing step is cut in halves).")]
SchedulerOpt = Annotated[Optional[str], typer.Option(
    help="Dask scheduler address (tcp://HOST:8786): the Gauss points' material updates run on its "
         "workers, one chunk of points each (worth it for DEM cells); same results as locally.")]
RegOpt = Annotated[str, typer.Option(
    help="local (default) or nonlocal:ell=LENGTH[,m=SHARE]: the points' inelastic stress averaged over "
         "the internal length ell [m] by an implicit-gradient operator, its share m (0, 1] in the "
         "equilibrium (mesh-objective softening; a band narrow enough for a laboratory specimen needs "
         "m < 1; docs/fem.md#regularization).")]
OutOpt = out_folder("Output folder (result.csv, fields_*.vtu, fields.pvd, fields.png, curve.png, "
                    "meta.json).")


def _finish(res, out: Path) -> None:
    from ..fem import write_result

    if res.stopped and len(res) <= 1:
        # only the consolidated state: no load step to report, and exit 0 would pass it as a result
        raise SolverError(f"no load step converged, nothing written: {res.stopped}")
    write_result(res, out)
    typer.echo(f"wrote {out / 'result.csv'} ({len(res) - 1} load steps, "
               f"{res.meta['gauss_points']} Gauss points, {res.meta['seconds']:.1f} s) and fields, figures")
    band = res.meta.get("band") or {}
    if band.get("angle_deg") is not None:
        theory = ", ".join(f"{k.capitalize()} {band[k]:.1f}°" for k in ("coulomb", "roscoe", "arthur") if k in band)
        pair = band.get("conjugate")
        if pair:  # a conjugate pair: each band, not one line through both
            where = (f"shear band at {pair[0]['angle_deg']:+.1f}° from the horizontal and its conjugate at "
                     f"{pair[1]['angle_deg']:+.1f}°")
        else:
            where = f"shear band at {band['angle_deg']:.1f}° from the horizontal"
        wide = f", {1e3 * band['width_m']:.3g} mm wide" + (" each" if pair else "") if band.get("width_m") else ""
        typer.echo(where + (f" ({theory})" if theory else "") + wide + f", after the peak at step {band['peak_step']}")
    if res.stopped:
        typer.echo(f"hmodel: warning: the run stopped early: {res.stopped}", err=True)


def _common(param, steps, solver, model, calibration, e0, e_ref):
    """The material (``-p`` on a calibrated model's parameters, at its void ratio ``--e0``) and
    the cell solver."""
    if steps < 1:
        raise InputError(f"--steps must be a positive integer, got {steps}")
    spec = specimen(model, calibration, e0, e_ref, 2)
    params = Params.parse_assignments(param, None if spec is None else spec.base)
    if spec is not None:
        if len(spec.e0) > 1:
            raise InputError("--e0 of a finite-element run is one void ratio")
        params = spec.at_e0([params], 1)[0]
    return params, get_solver(solver)


def _regularization(text: str, domain):
    """The parsed --regularization; a length the mesh does not resolve is a warning, before the
    run."""
    from ..fem.regularization import parse_regularization, unresolved

    reg = parse_regularization(text)
    warning = unresolved(reg, domain)
    if warning:
        typer.echo(f"hmodel: warning: {warning}", err=True)
    return reg


@app.command("biaxial")
def biaxial_cmd(
    p0: Annotated[str, typer.Option(help="Confining pressure, e.g. 200kPa (a number without unit is Pa, "
                                         "refused below 10 kPa).")] = "200kPa",
    axial_strain: Annotated[float, typer.Option(help=strain_help("Platen displacement / height after consolidation."))] = 0.05,
    mesh: MeshOpt = "8x16",
    size: Annotated[str, typer.Option(help="Specimen width x height [m].")] = "0.05x0.1",
    element: ElementOpt = "q4",
    platens: Annotated[str, typer.Option(help="smooth or rough platens.")] = "smooth",
    undrained: Annotated[bool, typer.Option("--undrained", help="Constant specimen volume (rigid "
                                                                 "lateral walls moving apart).")] = False,
    imperfection: Annotated[Optional[str], typer.Option(
        help="Weaker zone NAME=VALUE[,NAME=VALUE]@X,Y,R: other parameters (angles in degrees) in "
             "the disc of radius R [m] around (X, Y) [m], e.g. alpha0=50@0,0.05,0.006.")] = None,
    steps: StepsOpt = 100,
    solver: SolverOpt = "closed-form",
    param: ParamOpt = None,
    scheduler: SchedulerOpt = None,
    regularization: RegOpt = "local",
    model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None,
    out: OutOpt = Path("results/fem-biaxial"),
) -> None:
    """Plane-strain biaxial specimen: consolidation to p0, then drained (lateral pressure p0)
    or undrained compression by the top platen."""
    from ..fem import Domain, biaxial, parse_pair

    pressure = parse_pressure(p0, "--p0")
    if not (math.isfinite(axial_strain) and 0 < axial_strain < 1):
        raise InputError(f"--axial-strain must lie in (0, 1), got {axial_strain}")
    nxy = parse_pair(mesh, "--mesh", integer=True)
    wh = parse_pair(size, "--size", integer=False)
    params, cell_solver = _common(param, steps, solver, model, calibration, e0, e_ref)
    reg = _regularization(regularization, Domain(*wh, *nxy, element.lower()))
    with LazyProgress("FEM biaxial") as progress:
        res = biaxial(params, pressure, axial_strain, size=wh, mesh=nxy, element=element.lower(),
                      platens=platens, undrained=undrained, imperfection=imperfection, n_steps=steps,
                      solver=cell_solver, scheduler=scheduler, progress=progress, regularization=reg)
    _finish(res, out)


@app.command("footing")
def footing_cmd(
    p0: Annotated[str, typer.Option(help="Initial isotropic stress and surcharge, e.g. 100kPa (a number "
                                         "without unit is Pa, refused below 10 kPa).")] = "100kPa",
    settlement: Annotated[float, typer.Option(help=strain_help("Final settlement / footing width."))] = 0.05,
    mesh: MeshOpt = "20x10",
    layer: Annotated[str, typer.Option(help="Layer width x depth [m].")] = "1.0x0.5",
    width: Annotated[float, typer.Option(help="Footing width [m] (its edges on mesh nodes).")] = 0.2,
    smooth: Annotated[bool, typer.Option("--smooth", help="Smooth footing (default rough).")] = False,
    element: ElementOpt = "q4",
    steps: StepsOpt = 50,
    solver: SolverOpt = "closed-form",
    param: ParamOpt = None,
    scheduler: SchedulerOpt = None,
    regularization: RegOpt = "local",
    model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None,
    out: OutOpt = Path("results/fem-footing"),
) -> None:
    """Rigid strip footing on a layer consolidated to p0: the load-settlement curve."""
    from ..fem import Domain, footing, parse_pair

    pressure = parse_pressure(p0, "--p0")
    nxy = parse_pair(mesh, "--mesh", integer=True)
    lh = parse_pair(layer, "--layer", integer=False)
    params, cell_solver = _common(param, steps, solver, model, calibration, e0, e_ref)
    reg = _regularization(regularization, Domain(*lh, *nxy, element.lower()))
    with LazyProgress("FEM footing") as progress:
        res = footing(params, pressure, settlement, width=width, layer=lh, mesh=nxy,
                      element=element.lower(), rough=not smooth, n_steps=steps, solver=cell_solver,
                      scheduler=scheduler, progress=progress, regularization=reg)
    _finish(res, out)
