"""``hmodel stability``: second-order work and response envelopes along a biaxial path (2D), a
triaxial path (3D) or a loading program."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..loading import AXIAL_STEP
from ..params import Params
from ..units import parse_pressure
from .common3d import AzimuthsOpt, FabricOpt, OrderOpt, setup_3d
from .options import out_folder, param_option, strain_help
from .progress import LazyProgress

ParamOpt = param_option("sliding_rhs defaults to report in 2D and to equilibrium with --test triaxial "
                        "and in a 3D program, as in hmodel run; in 3D not n_theta, alpha_omega, "
                        "beta_omega (--order, --azimuths, --fabric).")


def stability(
    p0: Annotated[str, typer.Option(help="Confining pressure, e.g. 200kPa (a number without unit is Pa, "
                                         "refused below 10 kPa).")] = "200kPa",
    axial_strain: Annotated[float, typer.Option(help=strain_help("Axial strain after consolidation (its "
                                                                 "magnitude in extension)."))] = 0.1,
    undrained: Annotated[bool, typer.Option("--undrained", help="Isochoric (undrained) test.")] = False,
    test: Annotated[str, typer.Option(
        "--test", help="The laboratory test: biaxial (the 2D H-model) or triaxial (the 3D "
                       "H-model, axis 1 axial; envelopes in the Rendulic plane).")] = "biaxial",
    extension: Annotated[bool, typer.Option(
        "--extension", help="Triaxial extension: axial unloading (sig11 < sig22 = sig33); "
                            "--test triaxial only.")] = False,
    param: ParamOpt = None,
    at: Annotated[Optional[str], typer.Option(help="Axial strains (comma-separated) where full "
                                                   "envelopes are drawn.")] = None,
    probes: Annotated[int, typer.Option(help="Probe directions per state.")] = 72,
    magnitude: Annotated[Optional[float], typer.Option(
        help="Strain-probe magnitude (tensor norm); default: the norm of the path's strain "
             "increment, so that probes trigger the cell events the loading does.")] = None,
    loading_probe: Annotated[bool, typer.Option(
        "--loading-probe/--no-loading-probe",
        help="Count each loading increment as a probe from the state it starts from.")] = True,
    program: Annotated[Optional[Path], typer.Option(
        "--program", help="A loading program (TOML, see docs/programs.md; 2D or dim = 3) instead "
                          "of the laboratory test; --p0, --axial-strain, --undrained and --at do "
                          "not apply.")] = None,
    stress_magnitude: Annotated[float, typer.Option(help="Stress-probe magnitude, relative to p.")] = 1e-3,
    shear: Annotated[bool, typer.Option("--shear", help="Strain probes with the shear components: "
                                                         "(ε11, ε22, ε12) space in 2D, all six "
                                                         "components in 3D (not only the normal "
                                                         "ones).")] = False,
    every: Annotated[int, typer.Option(help="Probe every k-th increment of the path (every "
                                             "increment near the bifurcation domain).")] = 10,
    rendulic: Annotated[bool, typer.Option(
        "--rendulic/--no-rendulic",
        help="Triaxial test: half the strain probes on the Rendulic circle (dε22 = dε33), where "
             "the instability cone of an axisymmetric state opens first; the rest spread.")] = True,
    controllability: Annotated[Optional[str], typer.Option(
        "--controllability",
        help="How the loss of controllability is located: increments (the loading increments' "
             "d²W <= 0 for 5 increments; the 2D default) or secant (the first state from which "
             "the secant work to every later state of its stage is <= 0; the 3D default).")] = None,
    step: Annotated[float, typer.Option(help=strain_help("Axial strain increment of the laboratory test."))] = AXIAL_STEP,
    order: OrderOpt = None,
    azimuths: AzimuthsOpt = None,
    fabric: FabricOpt = 0.0,
    out: out_folder("Folder for CSV tables and PNG figures.") = Path("results/stability"),
) -> None:
    """Where the material can stop sustaining load: d²W of the loading increments, its minimum
    over probe directions at every k-th state, envelopes at --at, the bifurcation-domain entry
    and the loss of controllability."""
    from ..stability import run_study, write_study

    prog, params, pressure, sphere, at_strains = _inputs(
        p0, axial_strain, test, extension, param, at, magnitude, program, stress_magnitude,
        rendulic, controllability, step, order, azimuths, fabric)
    with LazyProgress("probing") as progress:
        study = run_study(params, program=prog, test=test, p0=pressure, axial_strain=axial_strain,
                          undrained=undrained, extension=extension, sphere=sphere, at=at_strains,
                          step=step, stress_magnitude=stress_magnitude, rendulic=rendulic,
                          every=every, n_probes=probes, magnitude=magnitude, shear=shear,
                          loading_probe=loading_probe, controllability=controllability,
                          progress=progress)
    write_study(study, out)
    for line in study.report(written=out):
        typer.echo(line)


def _inputs(p0, axial_strain, test, extension, param, at, magnitude, program, stress_magnitude,
            rendulic, controllability, step, order, azimuths, fabric):
    """The options read and checked before any work, in the command line's words: the program
    (or None), the parameters, the pressure of a laboratory test, its sphere (3D) and the axial
    strains of its envelopes."""
    from ..loading import Program
    from ..stability import RULES, TESTS

    if test not in TESTS:
        raise InputError(f"--test must be one of {', '.join(TESTS)}, got {test!r}")
    three_d = {"--order": order is not None, "--azimuths": azimuths is not None,
               "--fabric": fabric != 0.0, "--extension": extension, "--no-rendulic": not rendulic}
    if program is not None:
        given = [k for k, v in {"--test triaxial": test != "biaxial", **three_d}.items() if v]
        if given:
            raise InputError(f"{given[0]} does not apply with --program (its stages are the path; "
                             f"a 3D program's directions are its [sphere] table)")
    elif test == "biaxial" and any(three_d.values()):
        raise InputError(f"{next(k for k, v in three_d.items() if v)} is the 3D H-model's: use it "
                         f"with --test triaxial")
    if magnitude is not None and not (math.isfinite(magnitude) and magnitude > 0):
        raise InputError(f"--magnitude must be positive, got {magnitude}")
    if not (math.isfinite(step) and step > 0):
        raise InputError(f"--step must be a positive finite number, got {step}")
    prog = Program.from_toml(program) if program is not None else None
    if prog is not None and at:
        raise InputError("--at applies to the biaxial test, not to --program")
    sphere = pressure = None
    if prog is not None:
        params = prog.with_params(param)
    elif test == "triaxial":
        pressures, params, sphere, _ = setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                "closed-form")
        if len(pressures) != 1 or not isinstance(params, Params):
            raise InputError("hmodel stability follows one material point: give one --p0 and one "
                             "value per --param")
        pressure = float(pressures[0])
    else:
        params = Params.parse_assignments(param)
    if test == "biaxial":
        pressure = parse_pressure(p0, "--p0")
    try:
        at_strains = tuple(float(a) for a in at.split(",") if a.strip()) if at else ()
    except ValueError:
        raise InputError(f"--at expects comma-separated strains, got {at!r}") from None
    if not (math.isfinite(stress_magnitude) and stress_magnitude > 0):
        raise InputError(f"--stress-magnitude must be positive, got {stress_magnitude}")
    if controllability is not None and controllability not in RULES:
        raise InputError(f"--controllability must be one of {', '.join(RULES)}, got {controllability!r}")
    return prog, params, pressure, sphere, at_strains
