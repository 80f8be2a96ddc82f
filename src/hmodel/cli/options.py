"""Options shared by the commands, so that no command module imports another's: the outputs,
refused before any work when they cannot be written; the ``--workers`` option, capped at the
CPUs; ``--param``, ``--solver``, ``--p0``, ``--gate``/``--fallback`` and the calibrated model's
options; and the readers behind them (the 3D model's: :mod:`hmodel.cli.common3d`).

``--out ""`` is a malformed command line (exit 2); an output that exists as the wrong kind
(a file for a folder, a folder for a file) or lies where nothing can be written is refused
with exit 1 (:func:`hmodel.io.check_output_folder`, :func:`hmodel.io.check_output_file`).
A pressure typed without its unit is Pa, refused below 10 kPa
(:func:`hmodel.units.parse_pressure` with the option's name). Strains are fractions, and every
strain option says so (:func:`strain_help`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import check_output_file, check_output_folder
from ..params import UNITS, Params, parse_point_assignments
from ..workers import local_workers

#: What every strain option's help ends with: strains are fractions on the command line.
FRACTION = "(a fraction: 0.01 is 1 %)"


def strain_help(text: str) -> str:
    """The help of a strain option, saying that it is a fraction (inside its last parenthesis,
    where it ends with one)."""
    text = text.rstrip(".")
    if text.endswith(")"):
        return f"{text[:-1]}; {FRACTION[1:]}."
    return f"{text} {FRACTION}."


def param_option(sliding_rhs: str):
    """The ``--param``/``-p`` option, its help saying which ``sliding_rhs`` the command defaults
    to (``sliding_rhs``: a sentence)."""
    return Annotated[Optional[list[str]], typer.Option(
        "--param", "-p", metavar="NAME=VALUE",
        help="Model parameter, repeatable; angles in degrees. A comma list (phi_g=25,35) gives one "
             "material point per value, broadcast against --p0 (n_theta, radius, volume are shared). "
             f"{sliding_rhs} Names: " + ", ".join(f"{k} [{u}]" for k, u in UNITS.items()))]


#: ``--param`` of the 2D commands.
ParamOpt = param_option("sliding_rhs defaults to report in 2D (to equilibrium in 3D: the 3D tests and programs).")
SolverOpt = Annotated[str, typer.Option(
    "--solver", help="Cell solver: closed-form, surrogate (the shipped model), surrogate:MODEL_FILE or "
                     "dem:MESOSTRUCTURE (YADE cells: dem:standard, dem:hexagon-center, "
                     "dem:hexagon-unequal).")]
P0Opt = Annotated[str, typer.Option("--p0", help="Confining pressure(s): 200kPa, 0.2MPa, 2e5 (Pa; a number "
                                                  "without unit below 10 kPa is refused) or a comma list "
                                                  "100kPa,200kPa,400kPa.")]
GateOpt = Annotated[Optional[float], typer.Option(
    "--gate", help="Quantile level of a learned solver's trust score (e.g. 0.99) above which a cell "
                   "increment goes to --fallback; needs a model with a trust reference "
                   "('hmodel surrogate trust').")]
FallbackOpt = Annotated[Optional[str], typer.Option(
    "--fallback", help="Exact cell solver for the cells above --gate: closed-form (H-cell networks), or "
                       "a richer cell's DEM cell dem:MESO (its meso network; each cell carries its DEM state).")]


def positive(value: float, name: str) -> float:
    """``value`` of the option ``name``, refused unless positive and finite."""
    if not value > 0 or value != value or value == float("inf"):
        raise InputError(f"{name} must be a positive finite number, got {value}")
    return value


def axial_strain(value: float) -> float:
    """``--axial-strain``: a positive fraction below 1."""
    positive(value, "--axial-strain")
    if value >= 1:
        raise InputError(f"--axial-strain must be below 1, got {value}")
    return value


def material_points(param: list[str] | None, n_pressures: int, model=None) -> Params | list[Params]:
    """``--param`` with comma lists: one parameter set per material point, broadcast against the
    ``--p0`` list (equal lengths, or one of them 1); on the parameters of ``model`` (a
    :class:`~hmodel.calibrate.calibrated.Specimen`: a calibration's, and each point's e0) where
    given."""
    sets = parse_point_assignments(param, None if model is None else model.base)
    if len(sets) > 1 and n_pressures > 1 and len(sets) != n_pressures:
        raise InputError(f"--param lists give {len(sets)} material points and --p0 gives "
                         f"{n_pressures}: give equal lengths, or one value")
    if model is not None:
        sets = model.at_e0(sets, n_pressures)
    return sets[0] if len(sets) == 1 else sets


def _path(value) -> Path:
    if not str(value).strip():
        raise typer.BadParameter("the path is empty")
    return Path(value)


def _folder(ctx: typer.Context, value: Path | None) -> Path | None:
    if value is None or ctx.resilient_parsing:
        return value
    return check_output_folder(value)


def _file(ctx: typer.Context, value: Path | None) -> Path | None:
    if value is None or ctx.resilient_parsing:
        return value
    return check_output_file(value)


def out_folder(help: str, optional: bool = False):
    """The ``--out``/``-o`` option of a command that writes a folder (``optional``: None when
    not given)."""
    return Annotated[Optional[Path] if optional else Path, typer.Option("--out", "-o", help=help, parser=_path, callback=_folder,
                                        metavar="<path>")]


def out_file(help: str):
    """The ``--out``/``-o`` option of a command that writes one file."""
    return Annotated[Path, typer.Option("--out", "-o", help=help, parser=_path, callback=_file,
                                        metavar="<path>")]


def _workers(ctx: typer.Context, value: int | None) -> int | None:
    if value is None or ctx.resilient_parsing:
        return value
    usable = local_workers(value)
    if usable < value:  # more processes would share the same cores (the results are the same)
        typer.echo(f"hmodel: warning: --workers {value} is more than the CPUs ({usable}): using {usable}",
                   err=True)
    return usable


def workers_opt(help: str, optional: bool = False):
    """The ``--workers`` option: local processes, at least 1 (exit 2 below), capped at one per
    CPU with a warning (``optional``: None when not given)."""
    return Annotated[Optional[int] if optional else int, typer.Option("--workers", min=1, help=help,
                                                                      callback=_workers)]


ModelOpt = Annotated[Optional[str], typer.Option(
    "--model", help="Variant of the H-model (hmodel models): published (default), density (alias sand: "
                    "alpha0 from the specimen's void ratio --e0).")]
ContactFabricOpt = Annotated[bool, typer.Option(
    "--contact-fabric", help="Also write contact_fabric.csv and .png: the fabric of each point's carrying contacts "
                             "after consolidation and at the end (shares of the contacts and of the axial and lateral "
                             "stress by tilt from axis 1), to compare with a DEM sample's.")]
CalibrationOpt = Annotated[Optional[Path], typer.Option(
    "--calibration", help="Folder (or calibration.json) of a calibration: run its fitted model (parameters, "
                          "variant, 3D directions); -p changes parameters on top of it.")]
E0Opt = Annotated[Optional[str], typer.Option(
    "--e0", help="Void ratio of the specimen, or a comma list (one material point each, broadcast against "
                 "--p0): sets alpha0 through a model that uses e0 (sand), from its alpha0 at --e-ref.")]
ERefOpt = Annotated[Optional[float], typer.Option(
    "--e-ref", help="Void ratio at which the parameters' alpha0 holds (default: the calibration's).")]


def _void_ratios(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"--e0 must be void ratios (0.84 or 0.7,0.8), got {text!r}") from None
    for v in values:
        if not (v > 0 and v < float("inf")):
            raise InputError(f"--e0 must be positive void ratios, got {text!r}")
    return values


def specimen(model: str | None, calibration: Path | None, e0: str | None, e_ref: float | None, dim: int):
    """The run's :class:`~hmodel.calibrate.calibrated.Specimen` of --model, --calibration,
    --e0 and --e-ref (None when none is given)."""
    from ..calibrate.calibrated import Specimen

    return Specimen.make(model, calibration, None if e0 is None else _void_ratios(e0), e_ref, dim)
