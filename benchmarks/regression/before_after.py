"""The results of hmodel's main paths, recorded before a change and compared after it.

A refactoring must leave every number as it was. This script runs small versions of the main
paths through the Python API (2D biaxial tests on the closed form and the shipped surrogate,
the 3D laboratory tests, the cell mechanisms (Hertz-Mindlin contacts, rebirth, mix, the sand
and cross variants' sets), loading programs, a strain path, a finite-element biaxial test,
stability along biaxial and triaxial tests and a program, a failure surface, a calibration
and a surrogate's inference), and either stores every array it gets or compares them with
stored ones::

    python -m benchmarks.regression.before_after --record /tmp/before.npz   # before the change
    python -m benchmarks.regression.before_after --compare /tmp/before.npz  # after it

``--compare`` prints one row per array (its largest absolute difference relative to the
array's scale, the larger of its largest magnitude and 1) and exits with status 1 when any
difference exceeds :data:`TOLERANCE`, an array is missing, its shape or its NaNs moved, or a
text column changed. A reference holds the numbers of one machine and one set of libraries:
record it on the machine that compares (not in the repository). ``--only NAME`` runs the cases
whose name contains NAME. On a 2-core machine the run takes a few seconds, and about a minute
and a half more on a fresh checkout, whose compiled kernels are built first.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

#: The largest relative difference that passes.
TOLERANCE = 1e-10

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"

P0 = 2e5
STRAIN = 0.08


def _params_2d():
    from hmodel.params import Params

    return Params(n_theta=36)


def _params_3d():
    from hmodel.params import Params

    # the 3D commands' default closure (hmodel run triaxial and its siblings)
    return Params(sliding_rhs="equilibrium")


def _sphere():
    from hmodel.rev.sphere import Sphere

    return Sphere(order=9, n_azimuth=2)


def _columns(result, prefix: str = "") -> dict[str, np.ndarray]:
    """Every column of a path table (text columns as text)."""
    out = {}
    for name, values in result.columns.items():
        a = np.asarray(values)
        out[prefix + name] = a.astype(str) if a.dtype.kind in "OU" else a
    return out


# ------------------------------------------------------------------------------------ cases

def biaxial_drained() -> dict:
    from hmodel.loading import run_biaxial

    return _columns(run_biaxial(_params_2d(), P0, STRAIN))


def biaxial_undrained() -> dict:
    from hmodel.loading import run_biaxial

    return _columns(run_biaxial(_params_2d(), P0, STRAIN, undrained=True))


def biaxial_surrogate() -> dict:
    from hmodel.loading import run_biaxial
    from hmodel.solvers import get_solver

    return _columns(run_biaxial(_params_2d(), P0, 0.02, solver=get_solver("surrogate")))


def _triaxial(**kw) -> dict:
    from hmodel.loading import run_triaxial

    return _columns(run_triaxial(_params_3d(), P0, STRAIN, sphere=_sphere(), **kw))


def triaxial_drained() -> dict:
    return _triaxial()


def triaxial_undrained() -> dict:
    return _triaxial(undrained=True)


def triaxial_extension() -> dict:
    return _triaxial(extension=True)


def triaxial_surrogate() -> dict:
    from hmodel.cell.bihex import BiHexSolver
    from hmodel.loading import run_triaxial
    from hmodel.solvers import get_solver

    # hmodel run triaxial --solver surrogate: the shipped network of the equilibrium closure
    # steps the hexagons of every bi-hexagon
    solver = BiHexSolver(hexagon=get_solver("surrogate:equilibrium"))
    return _columns(run_triaxial(_params_3d(), P0, 0.005, sphere=_sphere(), solver=solver))


def true_triaxial() -> dict:
    from hmodel.loading import run_true_triaxial

    return _columns(run_true_triaxial(_params_3d(), P0, 0.5, STRAIN, sphere=_sphere()))


def oedometer() -> dict:
    from hmodel.loading import run_oedometer

    res = run_oedometer(_params_3d(), P0, STRAIN, sphere=_sphere())
    return {**_columns(res), "meta.K0": np.asarray(res.meta["K0"], float)}


def biaxial_batch() -> dict:
    from hmodel.loading import run_biaxial

    sets = [_params_2d(), _params_2d().with_(alpha0=math.radians(55.0))]
    return _columns(run_biaxial(sets, [1e5, 3e5], STRAIN, drop_failed=True))


def _mechanisms(params, **kw) -> dict:
    """Each cell mechanism on (docs/mechanisms.md): Hertz-Mindlin contacts alone and with each
    renewal, and the named variants' sets, drained and undrained."""
    from hmodel.loading import run_biaxial

    return _columns(run_biaxial(params, P0, STRAIN, **kw))


def biaxial_hertz() -> dict:
    return _mechanisms(_params_2d().with_(contact="hertz-mindlin"))


def biaxial_hertz_undrained() -> dict:
    return _mechanisms(_params_2d().with_(contact="hertz-mindlin"), undrained=True)


def biaxial_rebirth() -> dict:
    return _mechanisms(_params_2d().with_(contact="hertz-mindlin", renewal="rebirth"))


def biaxial_mix() -> dict:
    return _mechanisms(_params_2d().with_(contact="hertz-mindlin", renewal="mix"))


def _triaxial_mechanisms(options: dict, **kw) -> dict:
    from hmodel.loading import run_triaxial

    return _columns(run_triaxial(_params_3d().with_(contact="hertz-mindlin", **options), P0, STRAIN,
                                 sphere=_sphere(), **kw))


def triaxial_sand() -> dict:
    return _triaxial_mechanisms({"renewal": "mix", "lateral": "axisymmetric"})


def triaxial_sand_undrained() -> dict:
    return _triaxial_mechanisms({"renewal": "mix", "lateral": "axisymmetric"}, undrained=True)


def triaxial_cross() -> dict:
    return _triaxial_mechanisms({"cross_contacts": "frictionless"})


def _program(name: str):
    """An example program, 2D ones at the regression's n_theta, 3D ones at its sphere's order
    (the example's azimuths)."""
    from hmodel.loading import Program

    program = Program.from_toml(EXAMPLES / name)
    if program.sphere is not None:
        program = replace(program, sphere=replace(program.sphere, order=_sphere().order))
        return program, program.with_params(None)
    return program, program.with_params(["n_theta=36"])


def _run_program(name: str) -> dict:
    from hmodel.loading import ProgramFailed

    program, params = _program(name)
    try:
        res = program.run(params)
    except ProgramFailed as e:  # the liquefaction example ends so, by design
        res = e.result
    return _columns(res)


def program_2d() -> dict:
    return _run_program("unload-reload.toml")


def program_2d_cyclic() -> dict:
    return _run_program("drained-cyclic.toml")


def program_2d_liquefaction() -> dict:
    return _run_program("cyclic-undrained-liquefaction.toml")


def program_2d_rotating() -> dict:
    return _run_program("rotating-axes.toml")


def program_3d() -> dict:
    return _run_program("triaxial-unload-reload.toml")


def strain_path() -> dict:
    from hmodel.loading import run_strain_path

    t = np.linspace(0.0, 1.0, 21)
    eps = np.column_stack([0.01 * t, -0.004 * np.sin(math.pi * t), 0.003 * t ** 2])
    return _columns(run_strain_path(_params_2d(), eps, max_step=1e-3))


def _fem(res) -> dict:
    out = {f"rows.{c}": np.asarray(res.rows[c]) for c in res.columns}
    for s in res.snapshots:
        for name in ("u", "eps", "sig", "frac_sliding", "frac_open", "d2w"):
            out[f"snapshot{s.step}.{name}"] = np.asarray(getattr(s, name))
    out.update(_columns(res.reference, "reference."))
    return out


def fem_biaxial() -> dict:
    from hmodel import fem

    return _fem(fem.biaxial(_params_2d(), P0, 0.004, mesh=(2, 4), n_steps=4, n_saved=2))


def fem_biaxial_undrained() -> dict:
    from hmodel import fem

    return _fem(fem.biaxial(_params_2d(), P0, 0.004, mesh=(2, 4), n_steps=4, n_saved=2,
                            undrained=True, platens="rough"))


def _path_stability(ps) -> dict:
    """Every number of a path's stability, and its CSV tables as text."""
    from hmodel import stability

    out = {name: np.asarray(getattr(ps, name), float) for name in (
        "shear_strain", "loading_w", "check_strain", "check_min_w", "check_step",
        "check_magnitude", "bifurcation", "controllability", "bifurcation_step",
        "controllability_step")}
    out["found_by"] = np.array([ps.bifurcation_by, ps.controllability_by])
    for strain, envs in sorted(ps.envelopes.items()):
        for env in envs:
            out[f"envelope{strain:g}.{env.kind}.deps"] = env.deps
            out[f"envelope{strain:g}.{env.kind}.dsig"] = env.dsig
    with tempfile.TemporaryDirectory() as tmp:
        for name, write in stability.table_writers(ps).items():
            write(Path(tmp) / name)
            out[f"file.{name}"] = np.array((Path(tmp) / name).read_text())
    return out


def stability_biaxial() -> dict:
    from hmodel import stability

    return _path_stability(stability.along_biaxial(_params_2d(), P0, STRAIN, every=5,
                                                   n_probes=12, at=(0.01,)))


def stability_undrained() -> dict:
    from hmodel import stability

    return _path_stability(stability.along_biaxial(_params_2d(), P0, STRAIN, undrained=True,
                                                   every=5, n_probes=12, shear=True))


def stability_triaxial() -> dict:
    from hmodel import stability

    return _path_stability(stability.along_triaxial(_params_3d(), P0, 0.05, sphere=_sphere(),
                                                    every=5, n_probes=12, at=(0.02,)))


def stability_program() -> dict:
    from hmodel import stability

    program, params = _program("unload-reload.toml")
    return _path_stability(stability.along_program(program, params, every=10, n_probes=8))


def failure_surface() -> dict:
    from hmodel.failure_surface import failure_surface as surface

    fs = surface(_params_3d(), P0, [0.0, 30.0], sphere=_sphere(), step=2e-3, max_strain=0.1)
    out = {name: np.asarray(getattr(fs, name), float) for name in (
        "lode", "q_peak", "ratio", "phi", "principal", "strain", "lode_reached", "b_reached")}
    out["ended"] = np.array(fs.ended)
    out.update(_columns(fs.paths, "paths."))
    return out


def calibration() -> dict:
    from hmodel.calibrate import Test, fit
    from hmodel.loading import run_biaxial

    truth = _params_2d().with_(phi_g=math.radians(28.0))
    r = run_biaxial(truth, P0, 0.01, step=1e-3, iso_step=1e-4)
    c, s = r.stage("consolidation"), r.stage("shear")
    test = Test("drained", P0, np.asarray(s["eps11"]) - c["eps11"][-1], np.asarray(s["q"]),
                np.asarray(s["eps_v"]) - c["eps_v"][-1])
    cal = fit([test], ("phi_g",), base=_params_2d(), starts=1, max_nfev=4, step=1e-3,
              iso_step=1e-4)
    out = {"z": np.asarray(cal.z, float), "cost": np.asarray(cal.cost, float),
           "evaluations": np.asarray(cal.evaluations)}
    for name in sorted(cal.fitted):
        out[f"fitted.{name}"] = np.asarray(cal.fitted[name], float)
        out[f"stderr.{name}"] = np.asarray(cal.stderr[name], float)
    for t, (q, ev) in enumerate(zip(cal.prediction.q, cal.prediction.eps_v)):
        out[f"prediction{t}.q"] = np.asarray(q, float)
        out[f"prediction{t}.eps_v"] = np.asarray(ev, float)
    return out


def surrogate_inference() -> dict:
    from hmodel.cell import CellState
    from hmodel.solvers import get_solver

    solver = get_solver("surrogate")
    params = _params_2d()
    rng = np.random.default_rng(0)
    n = 64
    scale = 2e-4 * np.array([params.l10, params.l20])
    state = solver.initial(params, (n,))
    out = {}
    for k in range(3):  # three increments of a fixed batch of cells
        dl = -scale * rng.uniform(-0.5, 1.0, size=(n, 2))
        state, flags = solver.step(params, CellState(state.values), dl[:, 0], dl[:, 1])
        out[f"step{k}.state"] = np.asarray(state.values)
        out[f"step{k}.flags"] = np.asarray(flags.flags)
    return out


CASES: dict[str, Callable[[], dict]] = {f.__name__: f for f in (
    biaxial_drained, biaxial_undrained, biaxial_surrogate, biaxial_batch, triaxial_drained,
    triaxial_undrained, triaxial_extension, triaxial_surrogate, true_triaxial, oedometer,
    program_2d, program_2d_cyclic, program_2d_liquefaction, program_2d_rotating, program_3d,
    strain_path, biaxial_hertz, biaxial_hertz_undrained, biaxial_rebirth, biaxial_mix,
    triaxial_sand, triaxial_sand_undrained, triaxial_cross, fem_biaxial, fem_biaxial_undrained, stability_biaxial, stability_undrained,
    stability_triaxial, stability_program, failure_surface, calibration, surrogate_inference)}


# ------------------------------------------------------------------------------- record, compare

def compute(only: str | None = None, log=print) -> dict[str, np.ndarray]:
    """Every array of every case (of those whose name contains ``only``), keyed ``case/name``."""
    arrays = {}
    for case, run in CASES.items():
        if only and only not in case:
            continue
        t0 = time.perf_counter()
        for name, value in run().items():
            arrays[f"{case}/{name}"] = np.asarray(value)
        log(f"{case}: {time.perf_counter() - t0:.1f} s")
    return arrays


def difference(ref: np.ndarray, new: np.ndarray) -> float:
    """The largest absolute difference of two arrays relative to the reference's scale (the
    larger of its largest finite magnitude and 1); inf where they are not comparable (shape,
    NaN or infinity positions, text)."""
    if ref.shape != new.shape:
        return math.inf
    if ref.dtype.kind in "OUS" or new.dtype.kind in "OUS":
        return 0.0 if np.array_equal(ref.astype(str), new.astype(str)) else math.inf
    ref, new = ref.astype(float), new.astype(float)
    if not np.array_equal(np.isfinite(ref), np.isfinite(new)):
        return math.inf
    odd = ~np.isfinite(ref)
    if not np.array_equal(ref[odd], new[odd], equal_nan=True):
        return math.inf
    if ref.size == 0 or odd.all():
        return 0.0
    scale = max(float(np.abs(ref[~odd]).max()), 1.0)
    return float(np.abs(ref[~odd] - new[~odd]).max()) / scale


def compare(reference: dict[str, np.ndarray], arrays: dict[str, np.ndarray],
            out=sys.stdout) -> bool:
    """Print the table of differences; True when every array passes."""
    ok = True
    keys = sorted(set(reference) | set(arrays))
    width = max(len(k) for k in keys) if keys else 4
    print(f"{'path':<{width}}  {'max rel diff':>12}  pass", file=out)
    for key in keys:
        if key not in arrays or key not in reference:
            d, note = math.inf, " (missing now)" if key not in arrays else " (new)"
        else:
            d, note = difference(reference[key], arrays[key]), ""
        passed = d <= TOLERANCE
        ok &= passed
        print(f"{key:<{width}}  {d:>12.3g}  {'yes' if passed else 'NO'}{note}", file=out)
    return ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--record", type=Path, metavar="FILE.npz", help="store every array")
    mode.add_argument("--compare", type=Path, metavar="FILE.npz",
                      help="recompute and compare with a stored reference")
    ap.add_argument("--only", help="run only the cases whose name contains this")
    args = ap.parse_args(argv)
    log = lambda text: print(text, file=sys.stderr)  # noqa: E731
    t0 = time.perf_counter()
    if args.compare is not None:
        with np.load(args.compare, allow_pickle=False) as f:
            reference = {k: f[k] for k in f.files}
        if args.only:
            reference = {k: v for k, v in reference.items() if args.only in k.partition("/")[0]}
    arrays = compute(args.only, log)
    log(f"total: {time.perf_counter() - t0:.1f} s")
    if args.record is not None:
        np.savez_compressed(args.record, **arrays)
        log(f"recorded {len(arrays)} arrays in {args.record}")
        return 0
    return 0 if compare(reference, arrays) else 1


if __name__ == "__main__":
    sys.exit(main())
