"""The 3D model's options, shared by ``run triaxial | true-triaxial | oedometer``, ``stability
--test triaxial``, ``failure-surface`` and ``calibrate`` (triaxial kinds): a thin adapter of
the command line onto the 3D model's own rules (:mod:`hmodel.rev.model3d`: the cell a solver
makes, the parameters' defaults, the 2D model's parameters refused)."""

from __future__ import annotations

from dataclasses import replace
from typing import Annotated, Optional

import typer

from ..params import Params
from ..rev.model3d import assignments_3d
from ..rev.sphere import Sphere
from ..solvers import get_solver_3d
from ..units import parse_pressures
from .options import axial_strain, material_points, strain_help

Param3DOpt = Annotated[Optional[list[str]], typer.Option(
    "--param", "-p", metavar="NAME=VALUE",
    help="Model parameter, repeatable; angles in degrees. A comma list (phi_g=25,35) gives one "
         "material point per value, broadcast against --p0. In 3D: kn, kt_kn, phi_g, alpha0, "
         "radius, volume (hexagon, rectangle, box), g2, sliding_rhs (default here: equilibrium, "
         "or a learned cell's own; report in the 2D commands); the directions and fabric are "
         "--order, --azimuths, --fabric (not n_theta, alpha_omega, beta_omega).")]
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
AxialOpt = Annotated[float, typer.Option(help=strain_help("Axial strain after consolidation (its magnitude)."))]
StepOpt = Annotated[float, typer.Option(help=strain_help(
    "Axial strain increment (1e-4 here and in the 2D tests; calibrate's model runs at 1e-3)."))]
IsoStepOpt = Annotated[float, typer.Option(help=strain_help("Strain increment of the consolidation."))]
RadialOpt = Annotated[Optional[str], typer.Option(
    "--radial", help="How a drained triaxial test holds its sides: free (sig22 and sig33 each "
                     "held) or equal (one radial strain, eps22 = eps33, and (sig22 + sig33)/2 "
                     "held: a cylinder's; where the REV has no stiffness across the axis the free test "
                     "may bifurcate). Default: a --calibration's, else equal where the bi-hexagons "
                     "follow the lateral strain about their axis (lateral=axisymmetric: --model sand, "
                     "axisym), else free.")]
Solver3DOpt = Annotated[str, typer.Option(
    "--solver", help="Cell solver of the hexagons of every bi-hexagon: closed-form (compiled), or a "
                     "surrogate of the 2D H-cell, surrogate[:MODEL] (the learned 3D cell, on the "
                     "generic driver; plain 'surrogate' is the shipped network trained with the equilibrium "
                     "sliding_rhs; sliding_rhs defaults to the one the model was trained with); "
                     "or dem:bihexagon[:K=V,...], the bi-hexagon of spheres in YADE (slow).")]


def sphere(order: int | None, azimuths: int | None, fabric: float) -> Sphere:
    """The 3D discretization of --order, --azimuths, --fabric (deposition axis: axis 1)."""
    kw = {k: v for k, v in (("order", order), ("n_azimuth", azimuths)) if v is not None}
    return Sphere(**kw, alpha_omega=fabric, axis=(1.0, 0.0, 0.0))


def points_3d(param: list[str] | None, n_pressures: int, solver=None, model=None) -> Params | list[Params]:
    """``--param`` of a 3D run (:func:`~hmodel.cli.options.material_points`) by the 3D model's
    rules (:func:`~hmodel.rev.model3d.assignments_3d`): the 2D model's own parameters refused,
    naming their 3D equivalent; ``sliding_rhs`` defaulting to ``equilibrium``, or for a learned
    cell to the one its model was trained with; a calibrated ``model`` (a
    :class:`~hmodel.calibrate.calibrated.Specimen`) keeps its own."""
    base = None if model is None else model.base
    return material_points(assignments_3d(param, solver, base), n_pressures, model)


def setup_3d(p0: str, param, axial, order, azimuths, fabric, solver: str, model=None,
             p0_option: str = "--p0"):
    """What every 3D test reads from its options, checked before any work: the pressures, the
    material points' parameters, the sphere (a calibration's, changed by the options given) and
    the cell solver (:func:`hmodel.solvers.get_solver_3d`)."""
    pressures = parse_pressures(p0, p0_option)
    cells = get_solver_3d(solver)
    params = points_3d(param, len(pressures), cells, model)
    axial_strain(axial)
    shape = sphere(order, azimuths, fabric)
    if model is not None and model.sphere is not None:
        given = {k: v for k, v in (("order", order), ("n_azimuth", azimuths)) if v is not None}
        shape = replace(model.sphere, **given, **({"alpha_omega": fabric} if fabric else {}))
    return pressures, params, shape, cells
