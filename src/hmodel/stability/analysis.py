"""Stability along a path: a loading program, 2D or 3D, or a laboratory test (the 2D
model's biaxial test, the 3D model's triaxial test) as a program, probed between chunks of its
increments (:func:`along_program`)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..errors import InputError
from ..params import Params
from ..rev import RevState
from ..rev.model3d import check_3d_params
from ..rev.sphere import Sphere
from .locate import PathStability, _located, _rule
from .probes import _check, section_directions, strain_envelope, stress_envelope
from .work import second_order_work, tensor_norm


#: Probes at every state (not every k-th) once the least normalized d²W seen, over the probes
#: or the loading increments, falls below this: the critical region.
NEAR = 0.25

#: Probe magnitude before the path has made an increment (the consolidated state).
DEFAULT_MAGNITUDE = 1e-5


def along_biaxial(params, p0: float, axial_strain: float, undrained: bool = False,
                  every: int = 10, n_probes: int = 72, magnitude: float | None = None,
                  at: tuple[float, ...] = (), step: float | None = None,
                  stress_magnitude: float = 1e-3, shear: bool = False, progress=None,
                  loading_probe: bool = True, near: float = NEAR,
                  controllability: str | None = None) -> PathStability:
    """Drained or undrained biaxial test from p0 with strain probes (see :func:`along_program`)
    and full envelopes (strain probes, stress probes of ``stress_magnitude``·p) at the axial
    strains ``at``; ``shear`` probes ε12 too."""
    lateral = {} if undrained else {"sig22": float(p0)}
    program, at_steps = _lab_program("undrained biaxial" if undrained else "drained biaxial", p0,
                                     axial_strain, "undrained" if undrained else "drained",
                                     lateral, at, step)
    return along_program(program, params, every, n_probes, magnitude, shear=shear,
                         progress=progress, loading_probe=loading_probe, near=near,
                         at_steps=at_steps, stress_magnitude=stress_magnitude,
                         controllability=controllability)


def along_triaxial(params, p0: float, axial_strain: float, undrained: bool = False,
                   extension: bool = False, sphere: Sphere | None = None, every: int = 10,
                   n_probes: int = 72, magnitude: float | None = None, at: tuple[float, ...] = (),
                   step: float | None = None, stress_magnitude: float = 1e-3, shear: bool = False,
                   progress=None, loading_probe: bool = True, near: float = NEAR,
                   solver=None, rendulic: bool = True,
                   controllability: str | None = None) -> PathStability:
    """The triaxial test of the 3D H-model (:func:`hmodel.loading.lab_tests.run_triaxial`: axis
    1 axial, the shear strains held) from p0, drained (σ22 = σ33 = p0) or undrained (tr ε = 0,
    ε22 = ε33), in compression or with ``extension`` (ε11 decreasing), with strain probes
    along it (see :func:`along_program`; directions of :func:`triaxial_directions`, half on
    the Rendulic circle, or with ``rendulic=False`` all of :func:`probe_directions`; all six
    components with ``shear``) and envelopes in the Rendulic plane (strain probes and stress
    probes of ``stress_magnitude``·p, :func:`section_directions`) at the axial strains ``at``
    (magnitudes). ``sphere``: the 3D REV's directions (default ``Sphere()``); ``solver``: as
    :meth:`hmodel.loading.Program.run` of a 3D program. The located points are axial strains
    since consolidation (negative in extension); ``controllability``: as :func:`along_program`
    (default ``"secant"``)."""
    # the package's name, so that a rule put in its place there (a test's spy) is the one drawn
    from . import triaxial_directions

    if isinstance(params, Params):  # anything else is refused by the program, in its own words
        # as run_triaxial: the 3D fabric is the sphere's
        check_3d_params([n for n in ("alpha_omega", "beta_omega") if getattr(params, n) != 0],
                        "parameters")
    kind = "undrained" if undrained else "drained"
    lateral = {} if undrained else {"sig22": float(p0), "sig33": float(p0)}
    program, at_steps = _lab_program(
        f"{kind} triaxial {'extension' if extension else 'compression'}", p0, axial_strain, kind,
        lateral, at, step, sign=-1.0 if extension else 1.0,
        sphere=sphere if sphere is not None else Sphere())
    _check(n_probes, 1.0)
    directions = (lambda n: triaxial_directions(n, shear)) if rendulic else None
    return along_program(program, params, every, n_probes, magnitude, shear=shear,
                         progress=progress, loading_probe=loading_probe, near=near,
                         at_steps=at_steps, stress_magnitude=stress_magnitude, solver=solver,
                         directions=directions, controllability=controllability)


def _lab_program(name: str, p0: float, axial_strain: float, preset: str, lateral: dict,
                 at: tuple[float, ...], step: float | None, sign: float = 1.0,
                 sphere: Sphere | None = None):
    """The program of a laboratory test (isotropic consolidation to p0, then the stage named
    ``shear``: ``preset`` driven by ε11 = sign·axial_strain in increments ``step``, with the
    stress rows ``lateral``) and the increments of its shear stage where envelopes are drawn,
    labelled by their signed axial strain (the strains ``at`` are magnitudes). A 2D program,
    or with a ``sphere`` a 3D one."""
    from dataclasses import replace

    from ..loading import AXIAL_STEP, Program

    step = step or AXIAL_STEP
    if not (math.isfinite(axial_strain) and 0 < axial_strain < 1):
        raise InputError(f"axial strain must lie in (0, 1), got {axial_strain}")
    bad = [a for a in at if not 0 < a <= axial_strain]
    if bad:
        raise InputError(f"--at strains must lie on the path, in (0, {axial_strain}], got {bad}")
    n = max(1, math.ceil(axial_strain / step - 1e-9))
    shear_stage = {"name": "shear", "preset": preset, "eps11": sign * axial_strain, "steps": n,
                   **lateral}
    program = Program.from_dict({"name": name, "dim": 2 if sphere is None else 3,
                                 "stage": [{"preset": "iso", "p": float(p0)}, shear_stage]})
    if sphere is not None:
        program = replace(program, sphere=sphere)
    return program, {max(1, round(a / step)): sign * a for a in at}


def along_program(program, params, every: int = 10, n_probes: int = 72,
                  magnitude: float | None = None, shear: bool = False, progress=None,
                  loading_probe: bool = True, near: float = NEAR, at_steps: dict | None = None,
                  stress_magnitude: float = 1e-3, solver=None,
                  directions: np.ndarray | Callable[[int], np.ndarray] | None = None,
                  controllability: str | None = None) -> PathStability:
    """Second-order work along a loading program (:class:`hmodel.loading.Program`), 2D or 3D
    (``dim = 3``: probes of six components, on the program's REV, :meth:`Program.make_rev`).

    Strain probes (``n_probes`` directions) at every ``every``-th increment, and at every
    increment from when the least normalized d²W seen (probes or loading increments) is below
    ``near`` until the probes find some d²W ≤ 0. ``magnitude``: the probes' strain norm; None ties it to the loading increment
    (the norm of the path's last strain increment), so that a probe can trigger the same finite
    cell events (a contact opening, a cell starting to slide) as the loading does. With
    ``loading_probe``, each loading increment also counts as a probe from the state it starts
    from: the loading direction is itself a direction of the bifurcation domain's definition,
    so the domain is never found after the loss of controllability. ``at_steps`` maps
    increments of the stage named ``shear`` to labels (axial strains) where full envelopes are
    drawn (in 3D in the Rendulic plane, :func:`section_directions`). ``directions``: the
    probes' unit directions (n_probes, components) (default :func:`probe_directions`), or a
    function of n_probes that draws them once the probes are known to fit in memory.
    ``controllability``: how its loss is located (:data:`RULES`): ``"increments"``, where the
    loading increments' d²W turns ≤ 0 for 5 increments (the 2D default), or ``"secant"``, the
    first state from which the path's secant work to every later state of its stage is ≤ 0
    (the 3D default: the 3D model softens in single-increment drops, between which it reloads
    stiffly; :func:`_first_secant_loss`).
    """
    from ..loading import ProgramFailed

    _check(n_probes, magnitude if magnitude is not None else 1.0)
    if not (isinstance(every, (int, np.integer)) and every >= 1):
        raise InputError(f"--every must be a positive integer, got {every!r}")
    at_steps = dict(at_steps or {})
    rev = program.make_rev(params, solver)
    rule = _rule(controllability, rev.n_components)
    cells = (f"{params.n_theta:.4g} directions" if rev.n_components == 3
             else f"{rev.n_cells:,} bi-hexagons")
    # every probe of a state is a material point of one batched call
    rev.check_size(n_probes, f"{n_probes:,} probes of {cells}")
    if callable(directions):
        directions = directions(n_probes)
    # 3D envelopes: a section, the Rendulic plane
    drawn = section_directions(n_probes, 6) if rev.n_components == 6 else None
    seen = {"min": 1.0, "k": None, "eps": None, "sig": None, "mag": None, "entered": False}
    probed: dict[tuple, tuple[float, float]] = {}
    envs: dict = {}

    def chunk(state: RevState, k: int) -> int:
        e = state.eps[0]
        if seen["k"] is not None and 1 < k and k > seen["k"]:  # same stage: the mean increment
            de = (e - seen["eps"]) / (k - seen["k"])
            m = float(tensor_norm(de))
            seen["mag"] = m if m > 0 else seen["mag"]
            w = second_order_work(de, state.sig[0] - seen["sig"])[1]
            if np.isfinite(w):  # the loading increments' own d²W tells of the region too
                seen["min"] = min(seen["min"], float(w))
        mag = magnitude or seen["mag"] or DEFAULT_MAGNITUDE
        key = tuple(e)
        if key not in probed:
            env = strain_envelope(rev, state, n_probes, mag, shear, directions=directions)
            probed[key] = (env.min_normalized, mag)
            seen["min"] = min(seen["min"], env.min_normalized)
            seen["entered"] |= env.min_normalized <= 0
        if k - 1 in at_steps and at_steps[k - 1] not in envs:
            envs[at_steps[k - 1]] = (strain_envelope(rev, state, n_probes, mag, shear,
                                                     directions=drawn),
                                     stress_envelope(rev, state, n_probes, stress_magnitude))
        seen["k"], seen["eps"], seen["sig"] = k, e.copy(), state.sig[0].copy()
        # every state between the approach of the domain and its entry by the probes
        size = 1 if seen["min"] < near and not seen["entered"] else every
        later = [s - (k - 1) for s in at_steps if s > k - 1]
        return min([size] + later)

    def watch(fraction: float) -> None:
        if progress is not None:
            progress(fraction)

    try:
        res = program.run(params, solver=solver, progress=watch, chunk=chunk)
    except ProgramFailed as e:
        res = e.result
    ps = _located(res, probed, envs, loading_probe, rule)
    failed = [s for s in res.meta.get("stopped", []) if "failure" in s]
    if failed and not math.isfinite(ps.controllability_step) and len(res):
        # no strain increment carries the next targets: controllability under the stage's own
        # control is lost there, after the last converged state (its row and strain)
        ps.controllability_step = float(res["step"][-1])
        ps.controllability = float(ps.shear_strain[-1]) if len(ps.shear_strain) else float("nan")
        ps.controllability_by = "unsolvable increment"
    return ps

