"""``hmodel calibrate``: fit the H-model's parameters to measured biaxial (2D) or triaxial (3D)
tests."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..calibrate import fit, parse_data_spec
from ..calibrate.bayes import Noise
from ..calibrate.check import Check, check_at
from ..calibrate.fitting import METHODS, SEARCH_RULE
from ..calibrate.kinds import Kind, dimension
from ..calibrate.model import ISO_STEP
from ..calibrate.report import write
from ..errors import InputError
from ..params import Params
from ..solvers import get_solver, get_solver_3d
from ..variants import get_variant
from .common3d import AzimuthsOpt, FabricOpt, OrderOpt, RadialOpt, points_3d, sphere as sphere_of
from .options import FRACTION, out_folder, workers_opt
from .progress import LazyProgress

_DEFAULT_SEARCH = f"{SEARCH_RULE[0]}:{SEARCH_RULE[1]}"


def _bounds(items: list[str] | None) -> dict[str, tuple[float, float]]:
    out = {}
    for item in items or []:
        name, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        if not sep or not sep2 or not name.strip():
            raise InputError(f"--bounds expects NAME=LOW:HIGH (angles in degrees), got {item!r}")
        try:
            out[name.strip()] = (float(lo), float(hi))
        except ValueError:
            raise InputError(f"--bounds {item!r}: LOW and HIGH must be numbers") from None
    return out


def _search_rule(text: str) -> tuple[int, int] | None:
    """``--search-rule ORDER:AZIMUTHS`` or ``none``."""
    if text.strip().lower() == "none":
        return None
    order, _, m = text.partition(":")
    try:
        return int(order), int(m)
    except ValueError:
        raise InputError(f"--search-rule expects ORDER:AZIMUTHS (e.g. {_DEFAULT_SEARCH}) or none, "
                         f"got {text!r}") from None


def calibrate(
    data: Annotated[list[str], typer.Option("--data", help=f"A test, KIND:P0:FILE; KIND: drained or undrained (2D biaxial), {', '.join(k for k in Kind if k.dim == 3)} (3D); P0 with its unit (100kPa; a bare number is Pa, refused below 10 kPa); a CSV with columns eps11 (or eps_a), q and optionally eps_v, p: strains as fractions (0.01 is 1 %) since the end of consolidation, stresses in Pa, compression positive; repeatable.")],
    fit_: Annotated[Optional[str], typer.Option("--fit", help="Comma list of the parameters to fit (kn, kt_kn, phi_g, alpha0, alpha_omega, beta_omega, alpha0_spread, shear_modulus, poisson). Default: the model's (kn,kt_kn,phi_g,alpha0; shear_modulus,poisson,phi_g,alpha0 with Hertz-Mindlin contacts: hmodel models).")] = None,
    bounds: Annotated[Optional[list[str]], typer.Option("--bounds", help="Search range NAME=LOW:HIGH (angles in degrees); repeatable. Default: a range wide enough for real materials, narrowed to the cell model's training domain (a family surrogate, in 3D the one stepping the hexagons), outside which bounds are refused.")] = None,
    param: Annotated[Optional[list[str]], typer.Option("--param", "-p", metavar="NAME=VALUE", help="A fixed parameter (angles in degrees); repeatable. sliding_rhs defaults to report for 2D tests and to equilibrium for 3D ones (or a learned cell's own), as in hmodel run.")] = None,
    method: Annotated[str, typer.Option(help=f"Calibration method: {', '.join(METHODS)}.")] = "least-squares",
    starts: Annotated[int, typer.Option(help="Starting points of the least-squares fits (a Latin hypercube over the bounds).")] = 8,
    walkers: Annotated[int, typer.Option(help="bayes: emcee walkers (all evaluated in one batched call per step).")] = 32,
    steps: Annotated[int, typer.Option(help="bayes: steps of every walker.")] = 2000,
    noise: Annotated[Optional[str], typer.Option(help="bayes: noise levels q=FRACTION_OF_PEAK_Q,eps_v=STRAIN; default: the RMS the best fit leaves.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the design of starting points.")] = 0,
    workers: workers_opt("Processes the least-squares starts run in, at most one per CPU (the result is the same; the starts are independent).") = 1,
    step: Annotated[float, typer.Option(help=f"Axial strain increment of the model's tests {FRACTION}: 1e-3 here, coarser than hmodel run's 1e-4, as a calibration runs its tests for hundreds of parameter sets (the model's curves are interpolated at the tests' strains).")] = 1e-3,
    iso_step: Annotated[float, typer.Option(help=f"Strain increment of the model's consolidation {FRACTION}.")] = ISO_STEP,
    solver: Annotated[str, typer.Option(help="Cell solver: closed-form, surrogate[:NAME|:FILE] (a family model fits any material of its training domain), dem:... (3D: of the hexagons of every bi-hexagon).")] = "closed-form",
    order: OrderOpt = None, azimuths: AzimuthsOpt = None, fabric: FabricOpt = 0.0,
    radial: RadialOpt = None,
    search_rule: Annotated[str, typer.Option(help="3D: Lebedev order and azimuths ORDER:AZIMUTHS of the multi-start search, whose best point is then refined at the model's rule (--order, --azimuths); none: search at the model's rule.")] = _DEFAULT_SEARCH,
    check: Annotated[Optional[str], typer.Option("--check", metavar="SOLVER", help="Run the tests again at the optimum with this cell solver (the cell a surrogate learned: closed-form, dem:...) and report how far the calibrated model lies from it (check.csv, calibration.json, dashed in fit.png).")] = None,
    check_tol: Annotated[Optional[float], typer.Option(help="--check: warn where the calibrated model misses the check solver by more than this fraction of peak q (default 0.02).")] = None,
    model: Annotated[Optional[str], typer.Option("--model", help="The variant of the H-model (hmodel models): published (default), density (alias sand: each test from its own void ratio e0, which its --data must give).")] = None,
    scheduler: Annotated[Optional[str], typer.Option(help="A Dask scheduler's address (tcp://host:8786): the least-squares starts run on its workers instead of --workers local processes (the same result).")] = None,
    out: out_folder("Output folder.") = Path("results/calibration"),
) -> None:
    """Fit the H-model to measured biaxial (2D) or triaxial (3D) tests (least squares from several
    starts, or Bayesian)."""
    variant = get_variant(model)
    tests = [parse_data_spec(d) for d in data]
    dim = dimension([t.kind for t in tests])
    sphere = cells = None
    if dim == 2:
        given = [o for o, v in (("--order", order), ("--azimuths", azimuths)) if v is not None]
        given += ["--fabric"] if fabric != 0.0 else []
        given += ["--search-rule"] if search_rule != _DEFAULT_SEARCH else []
        if given:
            raise InputError(f"{', '.join(given)} set the 3D model's directions: the tests are 2D "
                             "biaxial ones (give triaxial-... kinds to calibrate the 3D model)")
        base = Params.parse_assignments(param)
        cells = get_solver(solver)
    else:
        cells = get_solver_3d(solver)
        base = points_3d(param, 1, cells)  # the 2D model's parameters refused, sliding_rhs's default
        if not isinstance(base, Params):
            raise InputError("--param gives one value per parameter in a calibration (no comma lists)")
        sphere = sphere_of(order, azimuths, fabric)
    checker = None
    if check is not None:  # refused before the fit, not after it
        checker = get_solver(check) if dim == 2 else get_solver_3d(check)
        check_tol = 0.02 if check_tol is None else check_tol
        if not (math.isfinite(check_tol) and check_tol >= 0):
            raise InputError(f"--check-tol must be a fraction of peak q >= 0, got {check_tol}")
    elif check_tol is not None:
        raise InputError("--check-tol applies to --check SOLVER, which is not given")
    names = list(variant.fitted) if fit_ is None else [n.strip() for n in fit_.split(",") if n.strip()]
    fixed = {item.partition("=")[0].strip() for item in param or []}
    both = [n for n in names if n in fixed]
    if both:
        raise InputError(f"{both[0]} is both fitted (--fit) and fixed (--param {both[0]}=...): drop one")
    for name, value in (("--step", step), ("--iso-step", iso_step)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive finite strain, got {value}")
    with LazyProgress("calibration (parameter sets run)") as progress:
        cal = fit(tests, names, _bounds(bounds), base, method, cells, starts, seed, step,
                  iso_step, walkers=walkers, steps=steps, noise=Noise.parse(noise) if noise else None,
                  sphere=sphere, search_rule=_search_rule(search_rule), workers=workers,
                  progress=progress, model=variant, scheduler=scheduler, radial=radial)
    checked = None
    if checker is not None:
        checked = check_at(cal.tests, cal.params, cal.prediction, checker, step, iso_step, cal.sphere,
                           cal.variant, cal.e_ref, cal.radial)
    written = write(cal, out, checked)
    typer.echo(f"{_fitted_text(cal)}; objective {cal.cost:.3g} after {cal.evaluations} parameter sets "
               f"({len(cal.failures)} failed)")
    if cal.failures:
        typer.echo("failed, most often: " + "; ".join(f"{n} × {why}" for n, why in cal.failure_reasons()))
    if cal.posterior is not None:
        typer.echo("posterior: " + ", ".join(f"{n} = {v['mean']:.5g} (90 %: {v['q05']:.5g} to {v['q95']:.5g})"
                                             for n, v in cal.posterior.summary.items())
                   + f"; acceptance {cal.posterior.acceptance:.2f}")
        if cal.posterior.warning:
            _warn(cal.posterior.warning)
    if cal.unidentified:
        typer.echo(f"not identified by these tests: {', '.join(cal.unidentified)} (uncertainty undefined)")
    for name, side in cal.at_bound.items():
        _warn(f"{name} ended at its {side} bound {cal.space.bound(name, side):g}: the best fit may lie "
              "beyond it (widen --bounds where the model allows, or check the tests' units)")
    if checked is not None:
        _echo_check(checked, check, check_tol)
    typer.echo("wrote " + ", ".join(str(p) for p in written))


def _fitted_text(cal) -> str:
    """``phi_g = 28.1 ± 0.3, kt_kn = 1.977 ± 3.6 (at its upper bound 2)``: a standard error the
    tests do not define is ``undefined``, a value on a bound says so."""
    at = cal.at_bound
    parts = []
    for n, v in cal.fitted.items():
        se = cal.stderr[n]
        text = f"{n} = {v:.5g} ± {se:.2g}" if math.isfinite(se) else f"{n} = {v:.5g} ± undefined"
        if n in at:
            text += f" (at its {at[n]} bound {cal.space.bound(n, at[n]):g})"
        parts.append(text)
    return ", ".join(parts)


def _warn(text: str) -> None:
    """A warning, as the other commands print theirs: the result stands, the user should look."""
    typer.echo(f"hmodel: warning: {text}", err=True)


def _echo_check(checked: Check, spec: str, tol: float) -> None:
    if checked.failed:
        _warn(f"the check solver {spec} failed at the optimum: {checked.failed}")
        return
    name, worst = checked.worst
    typer.echo(f"check at the optimum against {spec}: max |dq| / peak q {100 * worst:.2f} % ({name})")
    if worst > tol:
        _warn(f"that is more than --check-tol {100 * tol:.3g} %: the fitted parameters are "
              "the calibrated model's, not the check solver's")
