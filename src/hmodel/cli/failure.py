"""``hmodel failure-surface``: the 3D H-model's peak strength in the π-plane at one mean stress
(:func:`hmodel.failure_surface.failure_surface`), beside Mohr–Coulomb, Matsuoka–Nakai and
Lade–Duncan fitted at triaxial compression; the files and the summary are
:mod:`hmodel.failure_report`'s (``failure_surface.csv``, ``paths.csv``, ``failure_surface.json``,
``failure_surface.png``; a path that ended on the tension cut-off has no peak, and a warning
names it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ..failure_report import report_lines, write_failure_surface
from ..failure_surface import BEYOND, MAX_LODE_ANGLES, MAX_STRAIN, PAST_PEAK, STEP, failure_surface
from ..units import parse_pressures
from .common3d import AzimuthsOpt, FabricOpt, OrderOpt, Param3DOpt, points_3d, sphere as sphere_of
from .options import CalibrationOpt, E0Opt, ERefOpt, ModelOpt, out_folder, specimen, strain_help


def _angles(text: str) -> list[float]:
    """``--lode`` as numbers [deg] (the range is the API's check)."""
    try:
        values = [float(t) for t in str(text).split(",")]
    except ValueError:
        shown = repr(text) if len(str(text)) <= 80 else f"{str(text)[:60]!r}... ({len(str(text))} characters)"
        raise InputError(f"--lode must be Lode angles in degrees, comma-separated (e.g. 0,13,30,60), "
                         f"got {shown}") from None
    return values


def failure(p: Annotated[str, typer.Option("--p", help="Mean stress of every path: 200kPa, 0.2MPa or Pa (a number "
                                                         "without unit below 10 kPa is refused).")] = "200kPa",
            lode: Annotated[str, typer.Option(
                "--lode", help="Lode angles in degrees, comma-separated, each in [0, 60] (0: triaxial "
                               "compression, 60: extension); 0 is always added (the fits need it); at most "
                               f"{MAX_LODE_ANGLES} angles.")] = "0,13,30,60",
            param: Param3DOpt = None, order: OrderOpt = None, azimuths: AzimuthsOpt = None,
            fabric: FabricOpt = 0.0,
            step: Annotated[float, typer.Option(help=strain_help("Increment of the deviatoric strain along the ray."))] = STEP,
            max_strain: Annotated[float, typer.Option(help=strain_help("Largest deviatoric strain of a path."))] = MAX_STRAIN,
            out: out_folder("Output folder (failure_surface.csv/.json/.png, paths.csv).") = Path("results/failure-surface"),
            model: ModelOpt = None, calibration: CalibrationOpt = None, e0: E0Opt = None, e_ref: ERefOpt = None,
            ) -> None:
    """The failure surface in the π-plane: drained constant-p paths at each Lode angle to the
    peak of q_eq, beside Mohr–Coulomb, Matsuoka–Nakai and Lade–Duncan fitted at compression."""
    pressures = parse_pressures(p, "--p")
    if len(pressures) != 1:
        raise InputError(f"--p takes one mean stress, got {len(pressures)}")
    spec = specimen(model, calibration, e0, e_ref, 3)
    if spec is not None and len(spec.e0) > 1:
        raise InputError("--e0 of a failure surface is one void ratio (it runs one material point)")
    params = points_3d(param, 1, model=spec)
    if isinstance(params, list):
        raise InputError("failure-surface runs one parameter set: give -p NAME=VALUE without comma lists")
    angles = _angles(lode)
    sphere = sphere_of(order, azimuths, fabric)
    if spec is not None and spec.sphere is not None and order is None and azimuths is None:
        sphere = spec.sphere  # a calibration's directions, unless the options name others
    fs = failure_surface(params, pressures[0], angles, sphere=sphere, step=step, max_strain=max_strain,
                         past_peak=PAST_PEAK, beyond=BEYOND)
    info = write_failure_surface(fs, out, params, sphere)
    for line in report_lines(fs):
        typer.echo(line)
    typer.echo(f"wrote {out / 'failure_surface.csv'}, paths.csv, failure_surface.json and failure_surface.png")
    for line in info["warnings"]:
        typer.echo(f"hmodel: warning: {line}", err=True)
