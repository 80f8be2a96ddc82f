"""Material stability at the material point: response envelopes and second-order work.

From any state, *probes* apply small increments in many directions to copies of the state, in
one batched call (the state itself is never changed):

- strain probes: dε of magnitude m in N directions of the (ε11, ε22) plane (or, with shear, of
  (ε11, ε22, √2 ε12) space); the responses dσ draw Gudehus' response envelope;
- stress probes (mixed control): dσ of magnitude m·p in N directions of the (σ11, σ22) plane
  with σ12 held; the strain responses dε. A probe the material cannot sustain (Newton finds no
  strain increment) has a NaN response: controllability is lost in that direction.

Second-order work (Hill): d²W = dσ : dε = dσ11 dε11 + dσ22 dε22 + 2 dσ12 dε12, normalized by
|dσ| |dε| (tensor norms), i.e. the cosine between the two increments. Directions with
d²W ≤ 0 form the instability cone; its minimum over directions is the scalar indicator; the
first state along a path where it is ≤ 0 enters the bifurcation domain. The d²W of the path's
own increments changes sign where controllability is lost under the path's control (the peak of
q on an undrained path, the peak of σ11 on a drained one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from .errors import InputError
from .loading.compiled import (NOT_CONVERGED, cell_responses_of, fd_tangent, kernel_inputs, solve_point,
                               supports, trial)
from .loading.control import Tangent
from .loading.newton import NewtonSettings
from .rev import Rev, RevState


#: Newton's settings for the stress probes (those of the loading paths).
SETTINGS = NewtonSettings()


def _check(n: int, magnitude: float) -> None:
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"the number of probes must be a positive integer, got {n!r}")
    if not (math.isfinite(magnitude) and magnitude > 0):
        raise InputError(f"the probe magnitude must be positive and finite, got {magnitude!r}")


def probe_directions(n: int, shear: bool = False) -> np.ndarray:
    """Unit directions (n, 3) in (11, 22, 12) with tensor norm 1: a circle in the (11, 22)
    plane, or with ``shear`` a Fibonacci sphere in (11, 22, √2·12)."""
    if not shear:
        t = 2 * math.pi * np.arange(n) / n
        return np.column_stack([np.cos(t), np.sin(t), np.zeros(n)])
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    r = np.sqrt(1 - z * z)
    phi = math.pi * (3 - math.sqrt(5)) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z / math.sqrt(2)])


def tensor_norm(x: np.ndarray) -> np.ndarray:
    return np.sqrt(x[..., 0] ** 2 + x[..., 1] ** 2 + 2 * x[..., 2] ** 2)


def second_order_work(deps: np.ndarray, dsig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d²W, d²W / (|dσ| |dε|)) of increments (..., 3)."""
    w = dsig[..., 0] * deps[..., 0] + dsig[..., 1] * deps[..., 1] + 2 * dsig[..., 2] * deps[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        return w, w / (tensor_norm(deps) * tensor_norm(dsig))


@njit(cache=True, error_model="numpy")
def _strain_probe_kernel(values, eps, probes, geo, p, mode, volume0, sig, resp):
    out = np.empty_like(values)
    flags = np.empty((values.shape[0], 5), dtype=np.bool_)
    for k in range(probes.shape[0]):
        trial(values, eps, probes[k], geo, p, mode, volume0, out, flags, sig[k], resp)


@dataclass(frozen=True)
class Envelope:
    """Probes from one state: increments applied and responses, both (n, 3), and d²W."""

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

    @property
    def unstable(self) -> np.ndarray:
        """Directions of the instability cone (d²W ≤ 0), or where no response exists."""
        w = self.work
        return ~(w > 0)


def strain_envelope(rev: Rev, state: RevState, n: int = 72, magnitude: float = 1e-5,
                    shear: bool = False, point: int = 0) -> Envelope:
    """Stress responses to ``n`` strain probes of ``magnitude`` from material point ``point``."""
    _check(n, magnitude)
    probes = magnitude * probe_directions(n, shear)
    one = state.select(slice(point, point + 1))
    if supports(rev):
        k = int(one.set_index[0])
        geo, p = kernel_inputs(rev, k)
        sig = np.empty((n, 3))
        values = np.ascontiguousarray(one.cells.values[0])
        _strain_probe_kernel(values, one.eps[0], np.ascontiguousarray(probes), geo, p, rev.mode,
                             rev.volumes0[k], sig, cell_responses_of(rev.kernels[k], values))
    else:
        sig = rev.step(one.select(np.zeros(n, dtype=np.int64)), probes).sig
    return Envelope("strain", probes, sig - one.sig[0])


@njit(cache=True, error_model="numpy")
def _stress_probe_kernel(values, flags, eps, sig, K, targets, geo, p, mode, volume0, c, deps_out,
                         resp):
    n, m = values.shape
    buf = np.empty((4, n, m))
    bufflags = np.empty((4, n, 5), dtype=np.bool_)
    S = np.ones(3, dtype=np.bool_)
    M = np.eye(3)
    for k in range(targets.shape[0]):
        v = values.copy()
        f = flags.copy()
        e = eps.copy()
        s = sig.copy()
        Kk = K.copy()
        has = np.ones(1, dtype=np.bool_)
        status = solve_point(v, f, e, s, Kk, has, S, M, targets[k], geo, p, mode, volume0, c, 0,
                             buf, bufflags, resp, np.empty(0), np.zeros(1, dtype=np.int64))
        for j in range(3):
            deps_out[k, j] = np.nan if status == NOT_CONVERGED else e[j] - eps[j]


def stress_envelope(rev: Rev, state: RevState, n: int = 72, magnitude: float = 1e-3,
                    point: int = 0) -> Envelope:
    """Strain responses to ``n`` stress probes dσ = magnitude·p·(cos t, sin t, 0) from material
    point ``point`` (mixed control solved per probe; NaN where no response exists)."""
    _check(n, magnitude)
    if not supports(rev):
        raise InputError("stress probes need a compiled cell solver (the closed form or a meso surrogate)")
    one = state.select(slice(point, point + 1))
    dsig = magnitude * float(one.p[0]) * probe_directions(n)
    k = int(one.set_index[0])
    geo, p = kernel_inputs(rev, k)
    values = np.ascontiguousarray(one.cells.values[0])
    flags = np.ascontiguousarray(one.flags.flags[0])
    K = np.empty((3, 3))
    resp = cell_responses_of(rev.kernels[k], values)
    fd_tangent(values, one.eps[0], np.zeros(3), geo, p, rev.mode, rev.volumes0[k], SETTINGS.fd_step,
               np.empty_like(values), np.empty_like(flags), K, resp)
    deps = np.empty((n, 3))
    _stress_probe_kernel(values, flags, one.eps[0].copy(), one.sig[0].copy(), K,
                         np.ascontiguousarray(one.sig[0] + dsig), geo, p, rev.mode,
                         rev.volumes0[k], SETTINGS.packed(), deps, resp)
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
    pos = np.flatnonzero(v > 0)
    if not len(pos):
        return float("nan")
    cand = [i for i in np.flatnonzero((v <= 0) & (np.arange(len(v)) > pos[0]))
            if np.all(v[i:i + persist] <= 0)]
    if not cand:
        return float("nan")
    i = cand[0]
    x0, x1, v0, v1 = x[i - 1], x[i], v[i - 1], v[i]
    return float(x0 + (x1 - x0) * v0 / (v0 - v1)) if v0 != v1 else float(x1)


@dataclass
class PathStability:
    """Stability along a biaxial path: the path table, the loading increments' d²W, the probe
    minimum at checkpoints, envelopes at requested strains, and the located points."""

    result: "object"            # PathResult of the whole path
    shear_strain: np.ndarray    # axial strain since consolidation, per shear row
    loading_w: np.ndarray       # normalized d²W of each shear increment
    check_strain: np.ndarray    # axial strain of each probed state
    check_min_w: np.ndarray     # min over probe directions of normalized d²W there
    envelopes: dict             # axial strain -> (strain Envelope, stress Envelope)
    bifurcation: float          # first probed strain with some d²W <= 0 (NaN: none)
    controllability: float      # first strain where the loading increment's d²W <= 0


def along_biaxial(params, p0: float, axial_strain: float, undrained: bool = False,
                  every: int = 10, n_probes: int = 72, magnitude: float = 1e-5,
                  at: tuple[float, ...] = (), step: float | None = None,
                  stress_magnitude: float = 1e-3, shear: bool = False, progress=None) -> PathStability:
    """Drained or undrained biaxial test from p0 with strain probes at every ``every``-th
    increment and full envelopes (strain probes of ``magnitude``, stress probes of
    ``stress_magnitude``·p) at the axial strains ``at``; ``shear`` probes ε12 too."""
    from .loading import AXIAL_STEP, Recorder, consolidate, run_segment
    from .loading.paths import biaxial_segment

    _check(n_probes, magnitude)
    step = step or AXIAL_STEP
    if not (isinstance(every, (int, np.integer)) and every >= 1):
        raise InputError(f"--every must be a positive integer, got {every!r}")
    if not (math.isfinite(axial_strain) and 0 < axial_strain < 1):
        raise InputError(f"axial strain must lie in (0, 1), got {axial_strain}")
    bad = [a for a in at if not 0 < a <= axial_strain]
    if bad:
        raise InputError(f"--at strains must lie on the path, in (0, {axial_strain}], got {bad}")
    n = max(1, math.ceil(axial_strain / step - 1e-9))
    at_steps = {max(1, round(a / step)): a for a in at}
    checks = sorted(set(range(every, n + 1, every)) | set(at_steps) | {n})
    rev = Rev(params)
    rec = Recorder({"test": "undrained biaxial" if undrained else "drained biaxial", "p0": p0})
    state = consolidate(rev, [p0], recorder=rec)
    e0 = float(state.eps[0, 0])
    tangent = Tangent()
    done, cs, cw, envs = 0, [], [], {}
    for i, k in enumerate(checks):
        d = (k - done) * axial_strain / n
        seg = biaxial_segment(state, d, k - done, undrained, np.array([p0]))
        state = run_segment(rev, state, seg, rec, tangent=tangent)
        done = k
        env = strain_envelope(rev, state, n_probes, magnitude, shear)
        cs.append(state.eps[0, 0] - e0)
        cw.append(env.min_normalized)
        if k in at_steps:
            envs[at_steps[k]] = (env, stress_envelope(rev, state, n_probes, stress_magnitude))
        if progress is not None:
            progress((i + 1) / len(checks))
    res = rec.result()
    sh = res.stage("shear")
    cons = res.stage("consolidation")
    eps = np.column_stack([sh["eps11"], sh["eps22"], sh["eps12"]])
    sig = np.column_stack([sh["sig11"], sh["sig22"], sh["sig12"]])
    eps = np.vstack([[cons["eps11"][-1], cons["eps22"][-1], cons["eps12"][-1]], eps])
    sig = np.vstack([[cons["sig11"][-1], cons["sig22"][-1], cons["sig12"][-1]], sig])
    _, lw = loading_work(eps, sig)
    x = sh["eps11"] - e0
    cs, cw = np.array(cs), np.array(cw)
    first = np.flatnonzero(cw <= 0)
    return PathStability(res, x, lw, cs, cw, envs,
                         float(cs[first[0]]) if len(first) else float("nan"),
                         first_sign_change(x, lw))


def plot_envelopes(envelopes: dict, path, title: str) -> None:
    """Strain-probe response envelopes in the (dσ11, dσ22) plane, stress-probe strain responses
    in the (dε11, dε22) plane, and polar plots of the normalized d²W with the instability cone."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 4.8), layout="constrained")
    a = fig.add_subplot(1, 3, 1)
    b = fig.add_subplot(1, 3, 2)
    c = fig.add_subplot(1, 3, 3, projection="polar")
    for strain, (se, te) in sorted(envelopes.items()):
        lab = f"ε11 = {100 * strain:.2f} %"
        ds = np.vstack([se.dsig, se.dsig[:1]]) / 1e3
        a.plot(ds[:, 0], ds[:, 1], "-", label=lab)
        de = np.vstack([te.deps, te.deps[:1]]) * 1e6
        b.plot(de[:, 0], de[:, 1], ".-", ms=3, label=lab)
        t = np.arctan2(se.deps[:, 1], se.deps[:, 0])
        order = np.argsort(t)
        line, = c.plot(np.r_[t[order], t[order][:1]], np.r_[se.normalized[order], se.normalized[order][:1]], label=lab)
        neg = se.normalized[order] <= 0
        c.fill_between(t[order], -1, 1, where=neg, color=line.get_color(), alpha=0.15, step="mid")
    a.set(xlabel="dσ11 [kPa]", ylabel="dσ22 [kPa]", title="strain probes: stress response envelopes")
    b.set(xlabel="dε11 [10⁻⁶]", ylabel="dε22 [10⁻⁶]", title="stress probes: strain responses")
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
    with the entry into the bifurcation domain and the loss of controllability marked."""
    from matplotlib.figure import Figure

    sh = ps.result.stage("shear")
    fig = Figure(figsize=(12, 4.5), layout="constrained")
    a, b = fig.subplots(1, 2)
    x = 100 * ps.shear_strain
    a.plot(x, sh["q"] / 1e3, label="q")
    a.plot(x, sh["sig11"] / 1e3, label="σ11")
    a.set(xlabel="axial strain since consolidation [%]", ylabel="stress [kPa]")
    b.plot(x, ps.loading_w, lw=1, label="loading increment")
    b.plot(100 * ps.check_strain, ps.check_min_w, "o-", ms=3, label="minimum over probes")
    b.axhline(0, color="k", lw=0.8)
    for ax in (a, b):
        if math.isfinite(ps.bifurcation):
            ax.axvline(100 * ps.bifurcation, color="tab:orange", ls="--", label="bifurcation domain")
        if math.isfinite(ps.controllability):
            ax.axvline(100 * ps.controllability, color="tab:red", ls=":", label="loss of controllability")
    b.set(xlabel="axial strain since consolidation [%]", ylabel="normalized d²W = dσ:dε / (|dσ||dε|)",
          ylim=(-1.05, 1.05))
    a.legend(fontsize=8)
    b.legend(fontsize=8)
    fig.suptitle(title)
    fig.savefig(path, dpi=130)
