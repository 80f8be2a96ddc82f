"""``hmodel stability``: second-order work and response envelopes along a biaxial path (2D), a
triaxial path (3D) or a loading program."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs
from ..loading import AXIAL_STEP
from ..params import Params
from ..units import parse_pressure
from .progress import LazyProgress
from .options import out_folder
from .run import AzimuthsOpt, FabricOpt, OrderOpt, ParamOpt, _setup_3d

#: The laboratory tests of --test: the 2D model's biaxial test, the 3D model's triaxial test.
TESTS = ("biaxial", "triaxial")


def stability(
    p0: Annotated[str, typer.Option(help="Confining pressure, e.g. 200kPa.")] = "200kPa",
    axial_strain: Annotated[float, typer.Option(help="Axial strain after consolidation (its "
                                                     "magnitude in extension).")] = 0.1,
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
    step: Annotated[float, typer.Option(help="Axial strain increment of the laboratory test.")] = AXIAL_STEP,
    order: OrderOpt = None,
    azimuths: AzimuthsOpt = None,
    fabric: FabricOpt = 0.0,
    out: out_folder("Folder for CSV tables and PNG figures.") = Path("results/stability"),
) -> None:
    """Where the material can stop sustaining load: d²W of the loading increments, its minimum
    over probe directions at every k-th state, envelopes at --at, the bifurcation-domain entry
    and the loss of controllability."""
    from ..loading import Program
    from ..stability import (RULES, along_biaxial, along_program, along_triaxial, plot_envelopes,
                             plot_path, table_writers)

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
    sphere = None
    if prog is not None:
        params = prog.with_params(param)
    elif test == "triaxial":
        pressures, params, sphere, _ = _setup_3d(p0, param, axial_strain, order, azimuths, fabric,
                                                 "closed-form")
        if len(pressures) != 1 or not isinstance(params, Params):
            raise InputError("hmodel stability follows one material point: give one --p0 and one "
                             "value per --param")
        pressure = float(pressures[0])
    else:
        params = Params.parse_assignments(param)
    if test == "biaxial":
        pressure = parse_pressure(p0)
    try:
        at_strains = tuple(float(a) for a in at.split(",") if a.strip()) if at else ()
    except ValueError:
        raise InputError(f"--at expects comma-separated strains, got {at!r}") from None
    if not (math.isfinite(stress_magnitude) and stress_magnitude > 0):
        raise InputError(f"--stress-magnitude must be positive, got {stress_magnitude}")
    if controllability is not None and controllability not in RULES:
        raise InputError(f"--controllability must be one of {', '.join(RULES)}, got {controllability!r}")
    with LazyProgress("probing") as progress:
        common = {"every": every, "n_probes": probes, "magnitude": magnitude, "shear": shear,
                  "progress": progress, "loading_probe": loading_probe,
                  "controllability": controllability}
        if prog is not None:
            ps = along_program(prog, params, **common)
        elif test == "triaxial":
            ps = along_triaxial(params, pressure, axial_strain, undrained, extension, sphere,
                                at=at_strains, step=step, stress_magnitude=stress_magnitude,
                                rendulic=rendulic, **common)
        else:
            ps = along_biaxial(params, pressure, axial_strain, undrained, at=at_strains, step=step,
                               stress_magnitude=stress_magnitude, **common)
    drainage = "undrained" if undrained else "drained"
    if prog is not None:
        title = f"program {prog.name}"
    elif test == "triaxial":
        title = (f"{drainage} triaxial {'extension' if extension else 'compression'}, p0 = "
                 f"{pressure / 1e3:g} kPa (3D, Lebedev order {sphere.order}, "
                 f"{sphere.n_azimuth} azimuths)")
    else:
        title = f"{drainage} biaxial, p0 = {pressure / 1e3:g} kPa"
    files = {**table_writers(ps), "d2W-path.png": lambda p: plot_path(ps, p, title)}
    if ps.envelopes:
        files["envelopes.png"] = lambda p: plot_envelopes(ps.envelopes, p, title)
    write_outputs(out, files)
    fmt = lambda v: "none" if not math.isfinite(v) else f"{100 * v:.3f} %"  # noqa: E731
    row = lambda v: "" if not math.isfinite(v) else f" (row {v:.0f})"  # noqa: E731
    by = f", by the {ps.bifurcation_by}" if ps.bifurcation_by else ""
    reached = float(abs(ps.shear_strain[-1])) if len(ps.shear_strain) else 0.0
    if prog is None and reached < axial_strain - 0.5 * step:  # the program caught its failure
        typer.echo(f"the test ended at axial strain {100 * reached:.3f} %: the next increment "
                   f"could not be solved")
    typer.echo(f"bifurcation domain entered at axial strain {fmt(ps.bifurcation)}{row(ps.bifurcation_step)}"
               f"{by}; loss of controllability at {fmt(ps.controllability)}"
               f"{row(ps.controllability_step)}; wrote {out}")
