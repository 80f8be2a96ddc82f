"""``hmodel compare``: two cell solvers of the H-model (by default the closed form and the shipped
surrogate) on the same paths, path by path."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs, write_rows
from ..params import Params
from .options import FallbackOpt, GateOpt, ParamOpt, out_folder, strain_help
from .progress import LazyProgress


def compare(
    solver: Annotated[str, typer.Option("--solver", help="Solver compared with the reference: "
                                                         "surrogate, surrogate:NAME or surrogate:MODEL_FILE.")] = "surrogate",
    reference: Annotated[str, typer.Option("--reference", help="Reference solver: closed-form, or "
                                                               "dem:MESOSTRUCTURE (YADE cells, e.g. "
                                                               "dem:hexagon-center).")] = "closed-form",
    out: out_folder("Folder for deviations.csv and figures.") = Path("results/compare"),
    paths: Annotated[Optional[str], typer.Option(help="Comma-separated subset of: isotropic, drained, "
                                                      "undrained, unload-reload, oedometric, rotation.")] = None,
    axial_strain: Annotated[float, typer.Option(help=strain_help("Axial strain of the biaxial paths."))] = 0.1,
    step: Annotated[float, typer.Option(help=strain_help("Strain increment of both solvers."))] = 1e-3,
    iso_step: Annotated[float, typer.Option(help=strain_help("Strain increment of the consolidations."))] = 1e-4,
    param: ParamOpt = None,
    gate: GateOpt = None,
    fallback: FallbackOpt = None,
) -> None:
    """Run every comparison path with both solvers: overlaid curves, deviations and timings.

    Deviations are relative to the reference (the closed form, or a REV of DEM cells).
    """
    from ..compare import compare_path, plot_overlay, warm_up
    from ..surrogate.solver import gate_summary, gated_solver
    from ..loading import standard_paths
    from ..solvers import get_solver

    params = Params.parse_assignments(param)
    specs = standard_paths(axial_strain)
    if paths:
        names = [p.strip() for p in paths.split(",") if p.strip()]
        unknown = set(names) - {s.name for s in specs}
        if unknown:
            raise InputError(f"unknown comparison path(s) {', '.join(sorted(unknown))} "
                             f"(known: {', '.join(s.name for s in specs)})")
        specs = [s for s in specs if s.name in names]
    for v, name in ((step, "--step"), (iso_step, "--iso-step"), (axial_strain, "--axial-strain")):
        if not 0 < v < 1:
            raise InputError(f"{name} must lie in (0, 1), got {v}")
    other = gated_solver(solver, gate, fallback)
    ref_solver = get_solver(reference)
    rows, figures = [], {}
    warm = warm_up(params, [ref_solver, other], step, iso_step)
    if other.counts is not None:  # count the compared runs only (learned solvers count)
        other.counts.update(dict.fromkeys(other.counts, 0))
    with LazyProgress("comparing") as progress:
        for i, spec in enumerate(specs):
            ref, res, devs, st = compare_path(params, spec, other, step, iso_step, ref_solver)
            base = {"path": spec.name, "in_report": spec.in_report, "status": st["status"],
                    "reference": ref_solver.name, "seconds_reference": st["seconds_reference"],
                    f"seconds_{other.name}": st["seconds_other"],
                    "speed_ratio": st["seconds_reference"] / st["seconds_other"]}
            if res is None:
                rows.append({**base, "p0_kPa": ", ".join(f"{p / 1e3:g}" for p in spec.p0)})
            for d in devs:
                rows.append({**base, "p0_kPa": spec.p0[d["point"]] / 1e3, **d})
            if res is not None:
                figures[f"{spec.name}.png"] = (lambda n, a, b: lambda p: plot_overlay(
                    n, a, b, (ref_solver.name, other.name), p))(spec.name, ref, res)
            progress((i + 1) / len(specs))

    write_outputs(out, {"deviations.csv": lambda p: write_rows(rows, p), **figures})
    for r in rows:
        if r["status"] != "ok":
            typer.echo(f"{r['path']:<14} {other.name} {r['status']}")
            continue
        typer.echo(f"{r['path']:<14} p0 {r['p0_kPa']:>5.0f} kPa  q dev max {100 * r['q_max_dev_rel']:6.2f} % of peak, "
                   f"eps_v dev max {100 * r['eps_v_max_dev']:.3f} %  time {r['seconds_reference']:.2f} s vs "
                   f"{r[f'seconds_{other.name}']:.2f} s")
    if gate is not None:
        typer.echo(gate_summary(other))
    typer.echo("times after a warm-up run of every path (Numba compilation on a fresh install): "
               + ", ".join(f"{name} {s:.2f} s" for name, s in warm.items()))
    typer.echo(f"wrote {out / 'deviations.csv'} and {len(figures)} figures")
