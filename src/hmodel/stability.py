"""Material stability at the material point: response envelopes and second-order work.

From any state, *probes* apply small increments in many directions to copies of the state, in
one batched call (the state itself is never changed):

- strain probes: dε of magnitude m in N directions (:func:`probe_directions`): in 2D of the
  (ε11, ε22) plane (or, with shear, of (ε11, ε22, √2 ε12) space); in 3D of the principal
  (ε11, ε22, ε33) space (or, with shear, of all six components); the responses dσ draw
  Gudehus' response envelope;
- stress probes (mixed control): dσ of magnitude m·p in N directions of a plane of normal
  stresses (:func:`section_directions`: the (σ11, σ22) plane in 2D, the Rendulic plane
  (σ11, √2 σr), σr = σ22 = σ33, in 3D) with the other components held; the strain responses dε.
  A probe the material cannot sustain (Newton finds no strain increment) has a NaN response:
  controllability is lost in that direction.

Second-order work (Hill): d²W = dσ : dε = Σ dσij dεij (derived here in the REV's Voigt
components: dσ11 dε11 + dσ22 dε22 + 2 dσ12 dε12 in 2D; the three normal products plus twice
each of the three shear products in 3D), normalized by |dσ| |dε| (tensor norms), i.e. the
cosine between the two increments. Directions with d²W ≤ 0 form the instability cone; its
minimum over directions is the scalar indicator; the first state along a path where it is ≤ 0
enters the bifurcation domain. The d²W of the path's own increments changes sign where
controllability is lost under the path's control (the peak of q on an undrained path, the peak
of σ11 on a drained one; on a drained triaxial test σ11 - p0 = q).

Everything here is written for n components: 3 (the 2D REV, (11, 22, 12)) or 6 (the 3D REV,
:class:`hmodel.rev.rev3d.Rev3D`, (11, 22, 33, 23, 13, 12), tensor shear components).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError
from .loading.probes import strain_responses, stress_responses, supports
from .loading.newton import NewtonSettings
from .loading.result import COMPONENTS
from .rev import Rev, RevState
from .rev.sphere import Sphere


#: Newton's settings for the stress probes (those of the loading paths).
SETTINGS = NewtonSettings()


def _check(n: int, magnitude: float) -> None:
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"the number of probes must be a positive integer, got {n!r}")
    if not (math.isfinite(magnitude) and magnitude > 0):
        raise InputError(f"the probe magnitude must be positive and finite, got {magnitude!r}")


def shear_factors(n: int) -> np.ndarray:
    """Weights (n,) of the Voigt components (:data:`hmodel.loading.result.COMPONENTS`) in
    a:b = Σ a_ij b_ij: 1 on the normal components, 2 on the shear ones (tensor, not
    engineering, shear components: each appears twice in the sum)."""
    if n not in COMPONENTS:
        raise InputError(f"increments have 3 (2D) or 6 (3D) components, got {n}")
    return np.array([1.0 if c[0] == c[1] else 2.0 for c in COMPONENTS[n]])


def _fibonacci(n: int) -> np.ndarray:
    """n nearly uniform unit vectors (n, 3) on the sphere: the Fibonacci (golden-angle) spiral."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    r = np.sqrt(1 - z * z)
    phi = math.pi * (3 - math.sqrt(5)) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _halton_sphere(n: int, dim: int) -> np.ndarray:
    """n quasi-uniform unit vectors (n, dim): points 1..n of the Halton sequence (primes 2, 3,
    5, ...; point 0 is the cube's corner) mapped to a normal sample by the inverse normal CDF,
    then normalized (a normal vector's direction is uniform on the sphere). Deterministic, for
    any n, and low-discrepancy where a seeded random sample clusters."""
    from scipy.special import ndtri
    from scipy.stats import qmc

    h = qmc.Halton(d=dim, scramble=False)
    h.fast_forward(1)
    g = ndtri(h.random(n))
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def probe_directions(n: int, shear: bool = False, components: int = 3) -> np.ndarray:
    """Unit directions (n, components) with tensor norm 1, in the Voigt order of a REV of
    ``components`` components (:data:`hmodel.loading.result.COMPONENTS`).

    2D (3 components, (11, 22, 12)): a circle in the (11, 22) plane, or with ``shear`` a
    Fibonacci sphere in (11, 22, √2·12). 3D (6 components): a Fibonacci sphere in the principal
    space (11, 22, 33), the shears zero; or with ``shear`` a Halton set on the unit sphere of
    (11, 22, 33, √2·23, √2·13, √2·12) (:func:`_halton_sphere`)."""
    if components == 3 and not shear:
        t = 2 * math.pi * np.arange(n) / n
        return np.column_stack([np.cos(t), np.sin(t), np.zeros(n)])
    if components == 3:
        return _fibonacci(n) / np.sqrt(shear_factors(3))
    if components != 6:
        shear_factors(components)  # raises
    if not shear:
        return np.column_stack([_fibonacci(n), np.zeros((n, 3))])
    # Euclidean coordinates with the √2 on the shears have the tensor norm: back to components
    return _halton_sphere(n, 6) / np.sqrt(shear_factors(6))


def section_directions(n: int, components: int = 3) -> np.ndarray:
    """n unit directions (n, components) on a circle of a plane of normal components: the
    (11, 22) plane in 2D (:func:`probe_directions` without shear), the Rendulic plane of
    axisymmetric increments in 3D, (cos t, sin t/√2, sin t/√2, 0, 0, 0), whose coordinates
    are (x11, √2 xr) with xr = x22 = x33 (:func:`section`)."""
    if components != 6:
        return probe_directions(n, False, components)
    t = 2 * math.pi * np.arange(n) / n
    s = np.sin(t) / math.sqrt(2)
    return np.column_stack([np.cos(t), s, s, np.zeros((n, 3))])


def triaxial_directions(n: int, shear: bool = False) -> np.ndarray:
    """Probe directions (n, 6) of an axisymmetric (triaxial) path: ⌈n/2⌉ on the Rendulic circle
    (:func:`section_directions`), the rest spread (:func:`probe_directions` of 6 components).

    Derived here, and measured (docs/stability.md, "3D"): a state of a triaxial path is
    transversely isotropic about axis 1 (fabric and stress), its d²W is unchanged by swapping
    axes 2 and 3, and its instability cone opens in the plane dε22 = dε33 first: 36 directions
    there and 36 spread find the least d²W of 2000 spread ones, which 72 spread ones miss."""
    half = (n + 1) // 2
    return np.vstack([section_directions(half, 6), probe_directions(n - half, shear, 6)])


def section(x: np.ndarray) -> np.ndarray:
    """Coordinates (..., 2) of tensors x (..., n) in the plane of :func:`section_directions`:
    (x11, x22) in 2D; (x11, √2 xr), xr = (x22 + x33)/2, in 3D (the orthogonal projection on the
    Rendulic plane, in tensor norm)."""
    x = np.asarray(x, float)
    if x.shape[-1] != 6:
        return x[..., :2]
    return np.stack([x[..., 0], (x[..., 1] + x[..., 2]) / math.sqrt(2)], axis=-1)


def tensor_norm(x: np.ndarray) -> np.ndarray:
    """|x| = √(x:x) of tensors in Voigt components (..., 3 or 6)."""
    return np.sqrt(np.sum(shear_factors(x.shape[-1]) * x ** 2, axis=-1))


def second_order_work(deps: np.ndarray, dsig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d²W, d²W / (|dσ| |dε|)) of increments (..., 3 or 6): d²W = dσ:dε, the shear products
    counted twice (:func:`shear_factors`)."""
    w = np.sum(shear_factors(deps.shape[-1]) * (dsig * deps), axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return w, w / (tensor_norm(deps) * tensor_norm(dsig))


@dataclass(frozen=True)
class Envelope:
    """Probes from one state: increments applied and responses, both (n, 3 or 6), and d²W."""

    kind: str  # "strain" or "stress"
    deps: np.ndarray
    dsig: np.ndarray

    @property
    def work(self) -> np.ndarray:
        return second_order_work(self.deps, self.dsig)[0]

    @property
    def normalized(self) -> np.ndarray:
        return second_order_work(self.deps, self.dsig)[1]

    @property
    def min_normalized(self) -> float:
        w = self.normalized
        return float(np.nanmin(w)) if np.isfinite(w).any() else float("nan")


def strain_envelope(rev: Rev, state: RevState, n: int = 72, magnitude: float = 1e-5,
                    shear: bool = False, point: int = 0,
                    directions: np.ndarray | None = None) -> Envelope:
    """Stress responses to ``n`` strain probes of ``magnitude`` from material point ``point``
    of a 2D or 3D REV, in the directions of :func:`probe_directions`, or in the unit
    ``directions`` (n, components) given (e.g. :func:`section_directions`)."""
    _check(n, magnitude)
    c = rev.n_components
    if directions is None:
        directions = probe_directions(n, shear, c)
    elif np.shape(directions) != (n, c):
        raise InputError(f"probe directions must have shape ({n}, {c}), got {np.shape(directions)}")
    probes = magnitude * np.asarray(directions, float)
    one = state.select(slice(point, point + 1))
    if supports(rev):
        sig = strain_responses(rev, one, probes)
    else:
        sig = rev.step(one.select(np.zeros(n, dtype=np.int64)), probes).sig
    return Envelope("strain", probes, sig - one.sig[0])


def stress_envelope(rev: Rev, state: RevState, n: int = 72, magnitude: float = 1e-3,
                    point: int = 0) -> Envelope:
    """Strain responses to ``n`` stress probes dσ = magnitude·p·u from material point
    ``point``, u on the circle of :func:`section_directions` ((cos t, sin t, 0) in 2D, the
    Rendulic plane in 3D; the other components held), mixed control solved per probe; NaN
    where no response exists."""
    _check(n, magnitude)
    if not supports(rev):
        raise InputError("stress probes need a compiled cell solver (the closed form or a meso "
                         "surrogate; in 3D the closed-form bi-hexagon)")
    one = state.select(slice(point, point + 1))
    dsig = magnitude * float(one.p[0]) * section_directions(n, rev.n_components)
    deps = stress_responses(rev, one, one.sig[0] + dsig, SETTINGS)
    return Envelope("stress", deps, dsig)


def loading_work(eps: np.ndarray, sig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d²W and its normalized value of the increments between consecutive rows (n-1,)."""
    return second_order_work(np.diff(eps, axis=0), np.diff(sig, axis=0))


def first_sign_change(x: np.ndarray, values: np.ndarray, persist: int = 5) -> float:
    """First abscissa where ``values`` becomes ≤ 0 after being > 0 and stays ≤ 0 for
    ``persist`` values (or to the end), by linear interpolation; NaN when it never does.

    ``persist`` skips the isolated negative increments of single cell events (a contact
    opening is a small stress drop), which are not a loss of controllability of the sample."""
    v = np.asarray(values, float)
    i = _first_persistent(v, persist)
    if i is None:
        return float("nan")
    x0, x1, v0, v1 = x[i - 1], x[i], v[i - 1], v[i]
    return float(x0 + (x1 - x0) * v0 / (v0 - v1)) if v0 != v1 else float(x1)


#: Probes at every state (not every k-th) once the least normalized d²W seen, over the probes
#: or the loading increments, falls below this: the critical region.
NEAR = 0.25


@dataclass
class PathStability:
    """Stability along a path (a biaxial test or a loading program): the path table, the
    loading increments' d²W, the probe minimum at the probed states, envelopes at requested
    strains, and the located points.

    ``shear_strain`` and the located points are axial strains since consolidation (eps11
    minus its value there); ``*_step`` give the same points as rows (``step``) of the table,
    unambiguous on cyclic paths."""

    result: "object"            # PathResult of the whole path
    shear_strain: np.ndarray    # axial strain since consolidation, per row after it
    loading_w: np.ndarray       # normalized d²W of each increment after consolidation
    check_strain: np.ndarray    # axial strain of each probed state
    check_min_w: np.ndarray     # min over probe directions of normalized d²W there
    envelopes: dict             # axial strain -> (strain Envelope, stress Envelope)
    bifurcation: float          # first state with some d²W <= 0, probes or loading (NaN: none)
    controllability: float      # first strain where the loading increment's d²W <= 0 and stays
    check_step: np.ndarray = field(default_factory=lambda: np.empty(0, int))
    check_magnitude: np.ndarray = field(default_factory=lambda: np.empty(0))
    bifurcation_step: float = float("nan")
    controllability_step: float = float("nan")
    bifurcation_by: str = ""    # "probes" or "loading increment"
    controllability_by: str = "loading increments"  # or "unsolvable increment" (a program's end)


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
    from .loading.lab_tests import check_3d_params

    for name in ("alpha_omega", "beta_omega"):  # as run_triaxial: the 3D fabric is the sphere's
        if getattr(params, name, 0) != 0:
            check_3d_params([name], "parameters")
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

    from .loading import AXIAL_STEP, Program

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
    from .loading import ProgramFailed

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


#: Probe magnitude before the path has made an increment (the consolidated state).
DEFAULT_MAGNITUDE = 1e-5


#: How the loss of controllability is located along a path (:func:`along_program`).
RULES = ("increments", "secant")


def _rule(rule: str | None, n_components: int) -> str:
    """The rule of ``rule`` (None: ``increments`` in 2D, ``secant`` in 3D), checked."""
    rule = rule or ("secant" if n_components == 6 else "increments")
    if rule not in RULES:
        raise InputError(f"the controllability rule must be one of {', '.join(RULES)}, got {rule!r}")
    return rule


def _first_secant_loss(eps: np.ndarray, sig: np.ndarray, lw: np.ndarray,
                       segment: np.ndarray | None = None) -> int | None:
    """Row i of the first state, after a loading increment of d²W > 0, from which the path's
    secant work (σ_j − σ_i):(ε_j − ε_i) is ≤ 0 for every later state j of the same stage
    (``segment`` (n,): a label per row, the stage of a row; None: one stage): the path never
    makes up, under its stage's control, what it had at i (on a triaxial test, the peak of q).
    A cell event that the path makes up later, in one increment or in many, is skipped,
    whatever the increments' size; a drop made up by no later state is not, however stiffly the
    path reloads between drops (the sawtooth of the 3D model, docs/stability.md)."""
    segment = np.zeros(len(eps), int) if segment is None else np.asarray(segment)
    pos = np.flatnonzero(lw > 0)
    if not len(pos):
        return None
    for i in np.flatnonzero((lw <= 0) & (np.arange(len(lw)) > pos[0])):
        # the increment i -> i + 1 belongs to the stage of row i + 1; its states from there
        same = segment[i + 1:] == segment[i + 1]
        end = i + 1 + (int(np.argmin(same)) if not same.all() else len(same))
        w = second_order_work(eps[i + 1:end] - eps[i], sig[i + 1:end] - sig[i])[0]
        if np.all(w <= 0):
            return int(i)
    return None


def _located(res, probed: dict, envs: dict, loading_probe: bool,
             rule: str = "increments") -> PathStability:
    """Locate the entry into the bifurcation domain and the loss of controllability on a path:
    by the loading increments' own d²W (``rule="increments"``, :func:`first_sign_change`) or by
    the path's secant work (``"secant"``, :func:`_first_secant_loss`)."""
    cons = res["stage"] == "consolidation"
    first = int(np.flatnonzero(~cons)[0]) if (~cons).any() else len(res)
    start = max(first - 1, 0)  # the consolidated state, then every state after it
    comps = _components(res)  # the state's order: the probed states' strains are its rows
    eps = np.column_stack([res[f"eps{c}"] for c in comps])[start:]
    sig = np.column_stack([res[f"sig{c}"] for c in comps])[start:]
    steps = res["step"][start:]
    _, lw = loading_work(eps, sig)  # lw[i]: increment from row i to row i + 1
    e0 = eps[0, 0]
    x = eps[1:, 0] - e0
    # min normalized d²W over the probes from each state (NaN: not probed)
    rowmin = np.full(len(eps), np.nan)
    rowmag = np.full(len(eps), np.nan)
    index = {tuple(r): i for i, r in enumerate(eps)}
    for key, (w, m) in probed.items():
        i = index.get(key)
        if i is not None:
            rowmin[i], rowmag[i] = w, m
    checked = np.flatnonzero(np.isfinite(rowmin))
    by_probe = np.flatnonzero(rowmin <= 0)
    by_load = np.flatnonzero(lw <= 0) if loading_probe else np.empty(0, int)
    candidates = [(int(by_probe[0]), "probes")] if len(by_probe) else []
    if len(by_load):
        candidates.append((int(by_load[0]), "loading increment"))  # a probe from its start row
    entry, by = min(candidates) if candidates else (None, "")
    xs = np.r_[0.0, x]
    lost_step = float("nan")
    if rule == "secant":
        tags = [res["stage"][start:]] + ([res["cycle"][start:]] if "cycle" in res.columns else [])
        change = np.zeros(len(eps), bool)
        for t in tags:
            change[1:] |= t[1:] != t[:-1]
        i = _first_secant_loss(eps, sig, lw, np.cumsum(change))
        lost = float(xs[i]) if i is not None else float("nan")
        lost_step = float(steps[i]) if i is not None else float("nan")
    else:
        lost = first_sign_change(x, lw)
        if math.isfinite(lost):
            i = _first_persistent(lw)
            lost_step = float(steps[i + 1]) if i is not None else float("nan")
    return PathStability(
        res, x, lw, xs[checked], rowmin[checked], envs,
        float(xs[entry]) if entry is not None else float("nan"), lost,
        steps[checked], rowmag[checked],
        float(steps[entry]) if entry is not None else float("nan"), lost_step, by,
        controllability_by="loading increments" if rule == "increments" else "secant work")


def _components(res) -> tuple[str, ...]:
    """The Voigt components of a path table's states, in the REV's order (2D or 3D)."""
    return COMPONENTS[6 if "eps33" in res.columns else 3]


def _first_persistent(values: np.ndarray, persist: int = 5) -> int | None:
    """Index of the increment where :func:`first_sign_change` locates the sign change."""
    v = np.asarray(values, float)
    pos = np.flatnonzero(v > 0)
    if not len(pos):
        return None
    for i in np.flatnonzero((v <= 0) & (np.arange(len(v)) > pos[0])):
        if np.all(v[i:i + persist] <= 0):
            return int(i)
    return None


def table_writers(ps: PathStability) -> dict:
    """The CSV tables of a path's stability, as writers ``name -> write(path)`` for
    :func:`hmodel.io.write_outputs`: ``path.csv`` (the loading increments' normalized d²W),
    ``probes.csv`` (the probes' minimum per probed state), ``summary.csv`` (bifurcation-domain
    entry and loss of controllability) and, with envelopes, ``envelopes.csv``."""

    comps = _components(ps.result)
    normal = [f"{x}{c}" for x in ("eps", "sig") for c in comps if c[0] == c[1]]

    def write_path(p: Path) -> None:
        sh = ps.result
        sh = type(sh)({k: v[sh["stage"] != "consolidation"] for k, v in sh.columns.items()}, sh.meta)
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["step", "stage", "axial_strain", *normal, "q", "p", "d2W_loading_normalized"])
            for i in range(len(ps.shear_strain)):
                w.writerow([sh["step"][i], sh["stage"][i], ps.shear_strain[i],
                            *(sh[c][i] for c in normal), sh["q"][i], sh["p"][i], ps.loading_w[i]])

    def write_checks(p: Path) -> None:
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["step", "axial_strain", "probe_magnitude", "min_d2W_normalized"])
            w.writerows(zip(ps.check_step, ps.check_strain, ps.check_magnitude, ps.check_min_w))

    def write_envelopes(p: Path) -> None:
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["axial_strain", "probe", "kind", *(f"deps{c}" for c in comps),
                        *(f"dsig{c}" for c in comps), "d2W", "d2W_normalized"])
            for strain, envs in sorted(ps.envelopes.items()):
                for env in envs:
                    for k in range(len(env.deps)):
                        w.writerow([strain, k, env.kind, *env.deps[k], *env.dsig[k], env.work[k],
                                    env.normalized[k]])

    def write_summary(p: Path) -> None:
        p.write_text("quantity,axial_strain,step,found_by\n"
                     f"bifurcation_domain_entry,{ps.bifurcation},{ps.bifurcation_step},{ps.bifurcation_by}\n"
                     f"loss_of_controllability,{ps.controllability},{ps.controllability_step},{ps.controllability_by}\n")


    files = {"path.csv": write_path, "probes.csv": write_checks, "summary.csv": write_summary}
    if ps.envelopes:
        files["envelopes.csv"] = write_envelopes
    return files


def plot_envelopes(envelopes: dict, path, title: str) -> None:
    """Strain-probe response envelopes, stress-probe strain responses and polar plots of the
    normalized d²W with the instability cone, in the plane of :func:`section`: (dσ11, dσ22) and
    (dε11, dε22) in 2D; in 3D the Rendulic plane (dσ11, √2 dσr) and (dε11, √2 dεr), r the
    lateral (radial) mean (σ22 + σ33)/2 of an axisymmetric state."""
    from matplotlib.figure import Figure

    three_d = any(se.deps.shape[1] == 6 for se, _ in envelopes.values())
    lat = ("√2 dσr", "√2 dεr") if three_d else ("dσ22", "dε22")
    fig = Figure(figsize=(15, 4.8), layout="constrained")
    a = fig.add_subplot(1, 3, 1)
    b = fig.add_subplot(1, 3, 2)
    c = fig.add_subplot(1, 3, 3, projection="polar")
    for strain, (se, te) in sorted(envelopes.items()):
        lab = f"ε11 = {100 * strain:.2f} %"
        ds = section(np.vstack([se.dsig, se.dsig[:1]])) / 1e3
        a.plot(ds[:, 0], ds[:, 1], "-", label=lab)
        de = section(np.vstack([te.deps, te.deps[:1]])) * 1e6
        b.plot(de[:, 0], de[:, 1], ".-", ms=3, label=lab)
        u = section(se.deps)
        t = np.arctan2(u[:, 1], u[:, 0])
        order = np.argsort(t)
        line, = c.plot(np.r_[t[order], t[order][:1]], np.r_[se.normalized[order], se.normalized[order][:1]], label=lab)
        neg = se.normalized[order] <= 0
        c.fill_between(t[order], -1, 1, where=neg, color=line.get_color(), alpha=0.15, step="mid")
    plane = "\nin the Rendulic plane, σr = (σ22 + σ33)/2" if three_d else ""
    a.set(xlabel="dσ11 [kPa]", ylabel=f"{lat[0]} [kPa]",
          title=f"strain probes: stress response envelopes{plane}")
    b.set(xlabel="dε11 [10⁻⁶]", ylabel=f"{lat[1]} [10⁻⁶]", title="stress probes: strain responses")
    c.set_title("normalized d²W against strain-probe direction\n(shaded: instability cone, d²W ≤ 0)", fontsize=9)
    c.set_ylim(-1, 1)
    a.legend(fontsize=8)
    for ax in (a, b):
        ax.axhline(0, color="k", lw=0.5)
        ax.axvline(0, color="k", lw=0.5)
    fig.suptitle(title)
    fig.savefig(path, dpi=130)


def plot_path(ps: PathStability, path, title: str) -> None:
    """Normalized d²W of the loading increments and its minimum over probes along the path,
    with the entry into the bifurcation domain and the loss of controllability marked; against
    the axial strain since consolidation, or the row of the table where it goes back (cycles)."""
    from matplotlib.figure import Figure

    r = ps.result
    sh = {k: v[r["stage"] != "consolidation"] for k, v in r.columns.items()}
    d = np.diff(ps.shear_strain)
    monotonic = bool(np.all(d >= 0) or np.all(d <= 0))  # compression or extension
    if monotonic:
        x, xc, xb, xl = (100 * ps.shear_strain, 100 * ps.check_strain, 100 * ps.bifurcation,
                         100 * ps.controllability)
        label = "axial strain since consolidation [%]"
    else:
        x, xc, xb, xl = sh["step"], ps.check_step, ps.bifurcation_step, ps.controllability_step
        label = "row of the result table (step)"
    fig = Figure(figsize=(12, 4.5), layout="constrained")
    a, b = fig.subplots(1, 2)
    a.plot(x, sh["q"] / 1e3, label="q")
    a.plot(x, sh["sig11"] / 1e3, label="σ11")
    a.set(xlabel=label, ylabel="stress [kPa]")
    b.plot(x, ps.loading_w, lw=1, label="loading increment")
    b.plot(xc, ps.check_min_w, "o-", ms=3, label="minimum over probes")
    b.axhline(0, color="k", lw=0.8)
    for ax in (a, b):
        if math.isfinite(xb):
            ax.axvline(xb, color="tab:orange", ls="--", label=f"bifurcation domain ({ps.bifurcation_by})")
        if math.isfinite(xl):
            ax.axvline(xl, color="tab:red", ls=":", label="loss of controllability")
    b.set(xlabel=label, ylabel="normalized d²W = dσ:dε / (|dσ||dε|)", ylim=(-1.05, 1.05))
    a.legend(fontsize=8)
    b.legend(fontsize=8)
    fig.suptitle(title)
    fig.savefig(path, dpi=130)
