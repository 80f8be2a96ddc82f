"""``hmodel stability``: second-order work and response envelopes along a biaxial path."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs
from ..params import Params
from ..units import parse_pressure
from .progress import LazyProgress
from .run import ParamOpt


def stability(
    p0: Annotated[str, typer.Option(help="Confining pressure, e.g. 200kPa.")] = "200kPa",
    axial_strain: Annotated[float, typer.Option(help="Axial strain after consolidation.")] = 0.1,
    undrained: Annotated[bool, typer.Option("--undrained", help="Isochoric (undrained) test.")] = False,
    param: ParamOpt = None,
    at: Annotated[Optional[str], typer.Option(help="Axial strains (comma-separated) where full "
                                                   "envelopes are drawn.")] = None,
    probes: Annotated[int, typer.Option(help="Probe directions per state.")] = 72,
    magnitude: Annotated[float, typer.Option(help="Strain-probe magnitude (tensor norm).")] = 1e-5,
    stress_magnitude: Annotated[float, typer.Option(help="Stress-probe magnitude, relative to p.")] = 1e-3,
    shear: Annotated[bool, typer.Option("--shear", help="Strain probes in (ε11, ε22, ε12) space, "
                                                         "not only the (ε11, ε22) plane.")] = False,
    every: Annotated[int, typer.Option(help="Probe every k-th increment of the path.")] = 10,
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for CSV tables and PNG figures.")] = Path("results/stability"),
) -> None:
    """Where the material can stop sustaining load: d²W of the loading increments, its minimum
    over probe directions at every k-th state, envelopes at --at, the bifurcation-domain entry
    and the loss of controllability."""
    from ..stability import along_biaxial, plot_envelopes, plot_path

    params = Params.parse_assignments(param)
    pressure = parse_pressure(p0)
    try:
        at_strains = tuple(float(a) for a in at.split(",") if a.strip()) if at else ()
    except ValueError:
        raise InputError(f"--at expects comma-separated strains, got {at!r}") from None
    if not (math.isfinite(stress_magnitude) and stress_magnitude > 0):
        raise InputError(f"--stress-magnitude must be positive, got {stress_magnitude}")
    with LazyProgress("probing") as progress:
        ps = along_biaxial(params, pressure, axial_strain, undrained, every, probes, magnitude,
                           at_strains, stress_magnitude=stress_magnitude, shear=shear,
                           progress=progress)
    test = "undrained" if undrained else "drained"

    def write_path(p: Path) -> None:
        sh = ps.result.stage("shear")
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["axial_strain", "eps11", "eps22", "sig11", "sig22", "q", "p", "d2W_loading_normalized"])
            for i in range(len(ps.shear_strain)):
                w.writerow([ps.shear_strain[i], sh["eps11"][i], sh["eps22"][i], sh["sig11"][i],
                            sh["sig22"][i], sh["q"][i], sh["p"][i], ps.loading_w[i]])

    def write_checks(p: Path) -> None:
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["axial_strain", "min_d2W_normalized"])
            w.writerows(zip(ps.check_strain, ps.check_min_w))

    def write_envelopes(p: Path) -> None:
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["axial_strain", "probe", "kind", "deps11", "deps22", "deps12", "dsig11",
                        "dsig22", "dsig12", "d2W", "d2W_normalized"])
            for strain, envs in sorted(ps.envelopes.items()):
                for env in envs:
                    for k in range(len(env.deps)):
                        w.writerow([strain, k, env.kind, *env.deps[k], *env.dsig[k], env.work[k],
                                    env.normalized[k]])

    def write_summary(p: Path) -> None:
        p.write_text("quantity,axial_strain\n"
                     f"bifurcation_domain_entry,{ps.bifurcation}\nloss_of_controllability,{ps.controllability}\n")

    title = f"{test} biaxial, p0 = {pressure / 1e3:g} kPa"
    files = {"path.csv": write_path, "probes.csv": write_checks, "summary.csv": write_summary,
             "d2W-path.png": lambda p: plot_path(ps, p, title)}
    if ps.envelopes:
        files["envelopes.csv"] = write_envelopes
        files["envelopes.png"] = lambda p: plot_envelopes(ps.envelopes, p, title)
    write_outputs(out, files)
    fmt = lambda v: "none" if not math.isfinite(v) else f"{100 * v:.3f} %"  # noqa: E731
    typer.echo(f"bifurcation domain entered at axial strain {fmt(ps.bifurcation)}; "
               f"loss of controllability at {fmt(ps.controllability)}; wrote {out}")
