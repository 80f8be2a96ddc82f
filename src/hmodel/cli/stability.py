"""``hmodel stability``: second-order work and response envelopes along a biaxial path."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs
from ..params import Params
from ..units import parse_pressure
from .progress import LazyProgress
from .options import out_folder
from .run import ParamOpt


def stability(
    p0: Annotated[str, typer.Option(help="Confining pressure, e.g. 200kPa.")] = "200kPa",
    axial_strain: Annotated[float, typer.Option(help="Axial strain after consolidation.")] = 0.1,
    undrained: Annotated[bool, typer.Option("--undrained", help="Isochoric (undrained) test.")] = False,
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
        "--program", help="A loading program (TOML, see docs/programs.md) instead of the biaxial "
                          "test; --p0, --axial-strain, --undrained and --at do not apply.")] = None,
    stress_magnitude: Annotated[float, typer.Option(help="Stress-probe magnitude, relative to p.")] = 1e-3,
    shear: Annotated[bool, typer.Option("--shear", help="Strain probes in (ε11, ε22, ε12) space, "
                                                         "not only the (ε11, ε22) plane.")] = False,
    every: Annotated[int, typer.Option(help="Probe every k-th increment of the path (every "
                                             "increment near the bifurcation domain).")] = 10,
    out: out_folder("Folder for CSV tables and PNG figures.") = Path("results/stability"),
) -> None:
    """Where the material can stop sustaining load: d²W of the loading increments, its minimum
    over probe directions at every k-th state, envelopes at --at, the bifurcation-domain entry
    and the loss of controllability."""
    from ..loading import Program
    from ..stability import along_biaxial, along_program, plot_envelopes, plot_path, table_writers

    if magnitude is not None and not (math.isfinite(magnitude) and magnitude > 0):
        raise InputError(f"--magnitude must be positive, got {magnitude}")
    prog = Program.from_toml(program) if program is not None else None
    if prog is not None and at:
        raise InputError("--at applies to the biaxial test, not to --program")
    params = prog.with_params(param) if prog is not None else Params.parse_assignments(param)
    pressure = parse_pressure(p0)
    try:
        at_strains = tuple(float(a) for a in at.split(",") if a.strip()) if at else ()
    except ValueError:
        raise InputError(f"--at expects comma-separated strains, got {at!r}") from None
    if not (math.isfinite(stress_magnitude) and stress_magnitude > 0):
        raise InputError(f"--stress-magnitude must be positive, got {stress_magnitude}")
    with LazyProgress("probing") as progress:
        if prog is not None:
            ps = along_program(prog, params, every, probes, magnitude, shear=shear,
                               progress=progress, loading_probe=loading_probe)
        else:
            ps = along_biaxial(params, pressure, axial_strain, undrained, every, probes, magnitude,
                               at_strains, stress_magnitude=stress_magnitude, shear=shear,
                               progress=progress, loading_probe=loading_probe)
    test = "undrained" if undrained else "drained"

    title = (f"program {prog.name}" if prog is not None
             else f"{test} biaxial, p0 = {pressure / 1e3:g} kPa")
    files = {**table_writers(ps), "d2W-path.png": lambda p: plot_path(ps, p, title)}
    if ps.envelopes:
        files["envelopes.png"] = lambda p: plot_envelopes(ps.envelopes, p, title)
    write_outputs(out, files)
    fmt = lambda v: "none" if not math.isfinite(v) else f"{100 * v:.3f} %"  # noqa: E731
    step = lambda v: "" if not math.isfinite(v) else f" (row {v:.0f})"  # noqa: E731
    by = f", by the {ps.bifurcation_by}" if ps.bifurcation_by else ""
    typer.echo(f"bifurcation domain entered at axial strain {fmt(ps.bifurcation)}{step(ps.bifurcation_step)}"
               f"{by}; loss of controllability at {fmt(ps.controllability)}"
               f"{step(ps.controllability_step)}; wrote {out}")
