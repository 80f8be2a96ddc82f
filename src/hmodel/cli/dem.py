"""``hmodel dem``: cells, and a disk sample to calibrate on, solved by the DEM engine YADE (needs
the ``yade`` executable)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs, write_rows
from ..limits import check_count
from ..params import Params
from .options import out_folder, param_option, strain_help
from .progress import LazyProgress

ParamOpt = param_option("sliding_rhs defaults to equilibrium here: the DEM keeps every grain in "
                        "equilibrium (report in the 2D commands).")

app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="Cells, and a disk sample to calibrate on, solved by the DEM engine YADE "
                       "(apt-get install -y yade).")


def _params(param: list[str] | None, alpha0: float | None) -> Params:
    # The DEM keeps every grain in equilibrium, which is the closed form's `equilibrium`
    # sliding closure; `--param sliding_rhs=report` compares with the report's one instead.
    params = Params.parse_assignments(param, base=Params(sliding_rhs="equilibrium"))
    if alpha0 is not None:
        params = Params.from_strings({"alpha0": repr(alpha0)}, base=params)
    return params


@app.command("validate")
def validate_cmd(
    alpha0: Annotated[Optional[float], typer.Option(help="Opening angle α0 [deg].")] = None,
    strain: Annotated[float, typer.Option(help=strain_help("Total cell strain of every path."))] = 0.03,
    steps: Annotated[int, typer.Option(help="Increments per path.")] = 30,
    dim: Annotated[int, typer.Option(help="2: the standard H-cell; 3: the bi-hexagon of the 3D "
                                          "model (ten spheres).")] = 2,
    directions: Annotated[Optional[str], typer.Option(
        help="2D: path directions θ in the (ε1, ε2) plane [deg], comma-separated "
             "(default 0,45,90,-30).")] = None,
    probes: Annotated[Optional[int], typer.Option(
        help="2D: probe directions per start state (0: none; default 8).")] = None,
    paths: Annotated[Optional[str], typer.Option(
        help="3D: comma-separated paths, each a name (axial, triaxial, plane, mixed, opening, "
             "isotropic, unequal; default all) or a direction εn:εt1:εt2.")] = None,
    cross: Annotated[bool, typer.Option(
        "--cross/--no-cross", help="3D: also run every path with the two hexagons' lateral grains "
                                   "free to touch (contacts the closure ignores).")] = True,
    cross_friction: Annotated[bool, typer.Option(
        "--cross-friction/--frictionless-cross", help="3D, with --cross: the DEM's contacts between "
        "the two hexagons with the grains' friction, or frictionless (like for like with -p "
        "cross_contacts=frictionless).")] = True,
    param: ParamOpt = None,
    out: out_folder("Folder for the CSV table and PNG figures.") = Path("results/dem-validate"),
) -> None:
    """The DEM cell against the closed form. --dim 2: the standard cell on monotonic paths and
    single-increment probes (deviations.csv, paths.csv, validation.png, cell.png); --dim 3: the
    bi-hexagon on sliding and opening paths (deviations.csv, paths.csv, validation.png)."""
    params = _params(param, alpha0)
    if steps < 1:
        raise InputError(f"--steps must be a positive integer, got {steps}")
    if dim == 3:
        if directions is not None or probes is not None:
            raise InputError("--directions and --probes are the 2D cell's; the bi-hexagon's paths are --paths")
        return _validate_bihex(params, strain, steps, paths, cross, out, cross_friction)
    if dim != 2:
        raise InputError(f"--dim must be 2 or 3, got {dim}")
    if paths is not None:
        raise InputError("--paths is the bi-hexagon's (--dim 3); the 2D cell's paths are --directions")
    from ..dem.validate import plot_validation, validate, draw_cell

    directions = "0,45,90,-30" if directions is None else directions
    probes = 8 if probes is None else probes
    try:
        dirs = [float(d) for d in directions.split(",") if d.strip()]
    except ValueError:
        raise InputError(f"--directions expects comma-separated angles, got {directions!r}") from None
    if not dirs or not all(math.isfinite(d) for d in dirs):
        raise InputError(f"--directions expects finite angles, got {directions!r}")
    if probes < 0:
        raise InputError(f"--probes must be >= 0, got {probes}")
    with LazyProgress("DEM vs closed form") as progress:
        v = validate(params, strain=strain, steps=steps, directions_deg=dirs, n_probe=probes,
                     progress=progress)

    def write_paths(p: Path) -> None:
        rows = []
        for k, th in enumerate(v.directions_deg):
            for s, e in enumerate(v.strain):
                row = {"theta_deg": th, "strain": e}
                for name, arr in (("dem", v.dem), ("cf", v.cf), ("cf_fine", v.cf_fine)):
                    for i, q in enumerate(("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")):
                        row[f"{q}_{name}"] = arr[k, s, i]
                rows.append(row)
        write_rows(rows, p)

    i_end = len(v.directions_deg) - 1
    write_outputs(out, {"deviations.csv": lambda p: write_rows(v.rows, p),
                        "paths.csv": write_paths,
                        "validation.png": lambda p: plot_validation(v, p),
                        "cell.png": lambda p: draw_cell(v.runs[i_end], p)})
    worst = v.worst()
    typer.echo("max deviation from the refined closed form (relative to each quantity's range): "
               + ", ".join(f"{q} {100 * d:.2f} %" for q, d in worst.items())
               + f"; YADE {v.wall_s:.1f} s for {len(v.runs)} cells; wrote {out}")


def _validate_bihex(params: Params, strain: float, steps: int, paths: str | None, cross: bool,
                    out: Path, cross_friction: bool = True) -> None:
    """``hmodel dem validate --dim 3``: the DEM bi-hexagon against the closed form."""
    from ..dem.validate3d import PATHS, path_rows, plot_bihex_validation, validate_bihex

    chosen = []
    for item in (paths.split(",") if paths is not None else list(PATHS)):
        item = item.strip()
        if ":" in item:
            try:
                d = [float(x) for x in item.split(":")]
            except ValueError:
                raise InputError(f"--paths expects names or directions εn:εt1:εt2, got {item!r}") from None
            if len(d) != 3:
                raise InputError(f"a --paths direction has 3 components εn:εt1:εt2, got {item!r}")
            chosen.append((item, d))
        elif item:
            chosen.append(item)
    with LazyProgress("DEM bi-hexagon vs closed form") as progress:
        v = validate_bihex(params, strain=strain, steps=steps, paths=chosen, cross=cross, progress=progress,
                           cross_friction=cross_friction)
    write_outputs(out, {"deviations.csv": lambda p: write_rows(v.rows, p),
                        "paths.csv": lambda p: write_rows(path_rows(v), p),
                        "validation.png": lambda p: plot_bihex_validation(v, p)})
    worst = v.worst()
    typer.echo(f"max |ΔF| / max |F| {worst['dev_force']:.2e}, max |Δα| {worst['dev_alpha']:.2e} rad, "
               f"max |ΔVσ| / max |Vσ| {worst['dev_stress']:.2e} over {len(v.names)} path(s)"
               + ("" if not cross else
                  " (with cross contacts: {dev_force:.2e}, {dev_alpha:.2e} rad, {dev_stress:.2e})".format(**v.worst(True)))
               + f"; YADE {v.wall_s:.1f} s; wrote {out}")


@app.command("draw")
def draw_cmd(
    mesostructure: Annotated[str, typer.Option(help="standard, hexagon-center or hexagon-unequal.")] = "standard",
    alpha0: Annotated[Optional[float], typer.Option(help="Opening angle α0 [deg].")] = None,
    ratio: Annotated[Optional[float], typer.Option(help="Radius ratio of the richer cells.")] = None,
    strain: Annotated[float, typer.Option(help=strain_help("Cell strain (ε1, ε2) applied before drawing."))] = 0.01,
    theta: Annotated[float, typer.Option(help="Direction of that strain in the (ε1, ε2) plane [deg].")] = 0.0,
    steps: Annotated[int, typer.Option(help="Increments.")] = 10,
    param: ParamOpt = None,
    out: out_folder("Folder for cell.png.") = Path("results/dem-draw"),
) -> None:
    """Load a cell with the DEM and draw it: grains, and contacts by their normal force."""
    import numpy as np

    from ..cell.mesostructure import build
    from ..dem.scene import check_scene, simulate
    from ..dem.validate import draw_cell

    params = _params(param, alpha0)
    if steps < 1 or not (math.isfinite(strain) and math.isfinite(theta)):
        raise InputError("--steps must be positive, --strain and --theta finite")
    check_count(steps, "increments (--steps)")
    check_scene(1, steps, f"a DEM cell over {steps:,} increments")
    options = {} if ratio is None or mesostructure == "standard" else {"ratio": ratio}
    cell = build(mesostructure, params.radius, params.alpha0, **options)
    th = math.radians(theta)
    dl = np.array([-cell.l1 * strain / steps * math.cos(th), -cell.l2 * strain / steps * math.sin(th)])
    with LazyProgress("DEM"):
        (run,), _ = simulate([(cell, np.tile(dl, (steps, 1)))], params)
    write_outputs(out, {"cell.png": lambda p: draw_cell(run, p, title=f"{cell.name} cell, strain "
                                                        f"{100 * strain:g} % at θ = {theta:g}°")})
    typer.echo(f"wrote {out / 'cell.png'}")


@app.command("sample")
def sample_cmd(
    p0: Annotated[str, typer.Option("--p0", help="Consolidation pressure(s) [N/m, i.e. Pa for unit "
                                                 "thickness; Pa for spheres]: 100kPa, or a comma list "
                                                 "100kPa,200kPa (one test and CSV each); a number without "
                                                 "unit is Pa, refused below 10 kPa.")] = "100kPa",
    dim: Annotated[int, typer.Option(help="2: disks, biaxial tests; 3: spheres, triaxial tests.")] = 2,
    undrained: Annotated[bool, typer.Option("--undrained", help="Constant-area (constant-volume with "
                                                                "spheres: undrained) test instead of "
                                                                "drained (lateral stresses held at p0).")] = False,
    extension: Annotated[bool, typer.Option("--extension", help="Drained triaxial extension (--dim 3): "
                                                                "the axial strain is an extension.")] = False,
    axial_strain: Annotated[float, typer.Option(help=strain_help("Axial strain of the test (logarithmic)."))] = 0.1,
    disks: Annotated[Optional[int], typer.Option("--disks", "--spheres", help="Number of disks, or of "
                                                 "spheres with --dim 3 (default 2000 disks, 1500 spheres).")] = None,
    radius: Annotated[float, typer.Option(help="Mean radius (r_min + r_max)/2 [m].")] = 1.0,
    radius_ratio: Annotated[float, typer.Option(help="r_max / r_min.")] = 2.0,
    distribution: Annotated[str, typer.Option(help="Radii: uniform (in [r_min, r_max]), equal-area (disks: "
                                                   "every radius interval holds the same solid area) or "
                                                   "equal-volume (spheres: the same solid volume).")] = "uniform",
    contact: Annotated[str, typer.Option(help="Contact law: linear (springs --kn, --kt-kn) or "
                                              "hertz-mindlin (stiffnesses growing with the normal "
                                              "force, from --shear-modulus and --poisson).")] = "linear",
    kn: Annotated[Optional[float], typer.Option(help="Normal contact stiffness of the linear law "
                                                     "[N/m] (default 2e8).")] = None,
    kt_kn: Annotated[Optional[float], typer.Option(help="kt / kn of the linear law (default 0.5).")] = None,
    shear_modulus: Annotated[Optional[str], typer.Option(
        help="Hertz-Mindlin: the grains' shear modulus G, with its unit (29GPa) or in Pa.")] = None,
    poisson: Annotated[Optional[float], typer.Option(
        help="Hertz-Mindlin: the grains' Poisson ratio ν, in (-1, 0.5); E = 2G(1 + ν).")] = None,
    phi_g: Annotated[float, typer.Option(help="Contact friction angle φg during the test [deg].")] = 30.0,
    compaction_friction: Annotated[Optional[float], typer.Option(
        help="Contact friction angle during the consolidation [deg] (the lower, the denser); "
             "default 0, or φg with --porosity.")] = None,
    porosity: Annotated[Optional[float], typer.Option(
        help="Target porosity: the consolidation lowers the friction from --compaction-friction "
             "step by step until the porosity at p0 is at most this.")] = None,
    density: Annotated[float, typer.Option(help="Grain density [kg/m³] (disks of unit thickness, or "
                                                "spheres).")] = 2650.0,
    inertial_number: Annotated[Optional[float], typer.Option(
        help="Inertial number I = ε̇ d̄ √(ρ/p0) that sets the axial strain rate (default 1e-4).")] = None,
    strain_rate: Annotated[Optional[float], typer.Option(help="Axial strain rate [1/s], instead of "
                                                              "--inertial-number.")] = None,
    rows: Annotated[int, typer.Option(help="CSV rows after the first (one every axial-strain/rows).")] = 100,
    seed: Annotated[int, typer.Option(help="Seed of the radii and initial positions.")] = 0,
    damping: Annotated[float, typer.Option(help="Cundall's non-viscous damping.")] = 0.2,
    timeout: Annotated[float, typer.Option(help="Wall-clock limit of one test's YADE run [s].")] = 3600.0,
    out: out_folder("Folder for the CSVs, sample.json and sample.png.") = Path("results/dem-sample"),
) -> None:
    """A DEM sample to calibrate on: a periodic 2D assembly of polydisperse disks in YADE,
    consolidated to p0 and sheared (drained or undrained biaxial test), or with --dim 3 of
    spheres (drained or undrained triaxial compression, drained triaxial extension); writes
    KIND_P0kPa.csv (eps11,q,eps_v,p; for spheres eps_a,q,eps_v,p, coordination, sliding
    fraction, the stress tensor) and .npz per test, sample.json and sample.png. A test whose CSV
    exists in the folder is not run again. Contacts: linear springs, or Hertz-Mindlin with
    --contact hertz-mindlin --shear-modulus G --poisson ν."""
    from ..dem.sample import SampleSettings, run_sample
    from ..units import parse_pressure, parse_pressures

    pressures = parse_pressures(p0, "--p0")
    if inertial_number is not None and strain_rate is not None:
        raise InputError("give --inertial-number or --strain-rate, not both")
    if extension and dim != 3:
        raise InputError("--extension is a triaxial test of a sphere sample: add --dim 3 "
                         "(a disk sample runs drained and undrained biaxial compression)")
    if extension and undrained:
        raise InputError("--undrained --extension: a sphere sample runs drained and undrained "
                         "compression and drained extension")
    extra = {} if inertial_number is None else {"inertial_number": inertial_number}
    if contact == "hertz-mindlin" and (kn is not None or kt_kn is not None):
        raise InputError("--kn and --kt-kn set the linear law; Hertz-Mindlin's stiffnesses follow "
                         "from --shear-modulus and --poisson")
    extra.update({k: v for k, v in (("kn", kn), ("kt_kn", kt_kn)) if v is not None})
    if shear_modulus is not None:
        try:
            extra["shear_modulus"] = parse_pressure(shear_modulus)
        except InputError:
            raise InputError(f"--shear-modulus must be a positive modulus with its unit (29GPa) or "
                             f"in Pa, got {shear_modulus!r}") from None
    settings = SampleSettings(
        disks=disks if disks is not None else 2000 if dim == 2 else 1500, radius=radius,
        radius_ratio=radius_ratio, distribution=distribution, contact=contact, poisson=poisson,
        phi_g=phi_g, compaction_friction=compaction_friction, porosity=porosity,
        density=density, axial_strain=axial_strain, rows=rows, strain_rate=strain_rate, seed=seed,
        damping=damping, timeout=timeout, dim=dim, **extra)
    kind = "undrained" if undrained else "drained"
    if dim == 3:
        kind = "triaxial-" + ("extension" if extension else kind)
    meta = run_sample(settings, pressures, kind, out, progress=typer.echo)
    typer.echo(f"wrote {out} ({len(meta['tests'])} test(s) in sample.json)")
