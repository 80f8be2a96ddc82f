"""``hmodel calibrate``: fit the H-model's parameters to measured biaxial tests."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..calibrate import fit, parse_data_spec
from ..calibrate.bayes import Noise
from ..calibrate.fitting import METHODS
from ..calibrate.model import ISO_STEP
from ..calibrate.report import write
from ..errors import InputError
from ..params import Params
from ..solvers import get_solver
from .options import out_folder
from .progress import LazyProgress


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


def calibrate(
    data: Annotated[list[str], typer.Option("--data", help="A test, KIND:P0:FILE (drained or undrained; a CSV with columns eps11, q and optionally eps_v, p: strains since the end of consolidation, Pa); repeatable.")],
    fit_: Annotated[str, typer.Option("--fit", help="Comma list of the parameters to fit (kn, kt_kn, phi_g, alpha0, alpha_omega, beta_omega).")] = "kn,kt_kn,phi_g,alpha0",
    bounds: Annotated[Optional[list[str]], typer.Option("--bounds", help="Search range NAME=LOW:HIGH (angles in degrees); repeatable. Default: a range wide enough for real materials.")] = None,
    param: Annotated[Optional[list[str]], typer.Option("--param", "-p", metavar="NAME=VALUE", help="A fixed parameter (angles in degrees); repeatable.")] = None,
    method: Annotated[str, typer.Option(help=f"Calibration method: {', '.join(METHODS)}.")] = "least-squares",
    starts: Annotated[int, typer.Option(help="Starting points of the least-squares fits (a Latin hypercube over the bounds).")] = 8,
    walkers: Annotated[int, typer.Option(help="bayes: emcee walkers (all evaluated in one batched call per step).")] = 32,
    steps: Annotated[int, typer.Option(help="bayes: steps of every walker.")] = 2000,
    noise: Annotated[Optional[str], typer.Option(help="bayes: noise levels q=FRACTION_OF_PEAK_Q,eps_v=STRAIN; default: the RMS the best fit leaves.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the design of starting points.")] = 0,
    step: Annotated[float, typer.Option(help="Axial strain increment of the model's tests.")] = 1e-3,
    iso_step: Annotated[float, typer.Option(help="Strain increment of the model's consolidation.")] = ISO_STEP,
    solver: Annotated[str, typer.Option(help="Cell solver: closed-form, surrogate[:FILE], dem:...")] = "closed-form",
    out: out_folder("Output folder.") = Path("results/calibration"),
) -> None:
    """Fit the H-model to measured biaxial tests (least squares from several starts, or Bayesian)."""
    tests = [parse_data_spec(d) for d in data]
    base = Params.parse_assignments(param)
    names = [n.strip() for n in fit_.split(",") if n.strip()]
    fixed = {item.partition("=")[0].strip() for item in param or []}
    both = [n for n in names if n in fixed]
    if both:
        raise InputError(f"{both[0]} is both fitted (--fit) and fixed (--param {both[0]}=...): drop one")
    for name, value in (("--step", step), ("--iso-step", iso_step)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive finite strain, got {value}")
    with LazyProgress("calibration (parameter sets run)") as progress:
        cal = fit(tests, names, _bounds(bounds), base, method, get_solver(solver), starts, seed, step,
                  iso_step, walkers=walkers, steps=steps, noise=Noise.parse(noise) if noise else None,
                  progress=progress)
    written = write(cal, out)
    fitted = ", ".join(f"{n} = {v:.5g} ± {cal.stderr[n]:.2g}" for n, v in cal.fitted.items())
    typer.echo(f"{fitted}; objective {cal.cost:.3g} after {cal.evaluations} parameter sets "
               f"({len(cal.failures)} failed)")
    if cal.posterior is not None:
        typer.echo("posterior: " + ", ".join(f"{n} = {v['mean']:.5g} (90 %: {v['q05']:.5g} to {v['q95']:.5g})"
                                             for n, v in cal.posterior.summary.items())
                   + f"; acceptance {cal.posterior.acceptance:.2f}")
        if cal.posterior.warning:
            typer.echo("warning: " + cal.posterior.warning)
    if cal.unidentified:
        typer.echo(f"not identified by these tests: {', '.join(cal.unidentified)}")
    typer.echo("wrote " + ", ".join(str(p) for p in written))
