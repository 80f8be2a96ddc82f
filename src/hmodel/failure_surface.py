"""The failure surface of the 3D H-model in the π-plane (docs/model3d.md, "Failure
surface").

For each Lode angle θ (0° triaxial compression … 60° triaxial extension, the convention of
:func:`hmodel.loading.result.lode_b`) a drained path at constant mean stress p runs from
isotropic consolidation at p with the stress kept on the ray of angle θ in the π-plane, to the
peak of q_eq = sqrt(3 J2). Principal axes 1, 2, 3 carry the major, intermediate and minor
stresses; on the ray,

    σ_i = p + (2/3) q_eq cos θ_i,    θ_1 = θ, θ_2 = θ - 2π/3, θ_3 = θ + 2π/3,

so that b = (σ2 - σ3)/(σ1 - σ3) and tan θ = √3 b/(2 - b) are those of the ray.

**Control (the choice made here): strain control along the ray, mixed with two stress rows.**
The six rows of each increment are

- a strain row: the deviatoric strain along the ray, ε_s = (2/3) Σ_i cos θ_i ε_ii, increased
  by ``step`` each increment (ε_s is work-conjugate to q_eq on the ray, and is ε_q = (2/3)(ε1 - ε3)
  in triaxial compression);
- a stress row: p = (σ11 + σ22 + σ33)/3 held at p;
- a stress row: e·σ = 0 with e = -sqrt(2/3) (sin θ_1, sin θ_2, sin θ_3), the unit deviatoric direction
  normal to the ray in the π-plane: the stress stays on the ray (b and θ constant);
- three strain rows: the shear strains ε23, ε13, ε12 held at 0 (fixed principal axes).

The three normal rows are pairs of work-conjugate variables (p with ε_v, q_eq with ε_s, e·σ with
e·ε), so the path is a proper mixed control in the sense of Nicot's controllability, like the
drained triaxial test (lateral stresses and axial strain); strain control on the deviator goes
through the peak, which is found to one increment, and past it. A path ends past its peak
(q_eq is ``past_peak`` below its maximum so far *and* ε_s grew by ``beyond`` since that
maximum: cell events make q_eq drop and recover within a few increments), at ``max_strain``,
or where Newton fails (the limit state under this control, or a cell event it cannot straddle:
with ``sliding_rhs="report"`` a cell sliding with T1 < 0 loses its contact at once and the
stress jumps, see :class:`hmodel.params.Params`): the peak is the largest q_eq among the
converged states, and ``FailureSurface.ended`` says which ending it was. The model's
extension side may have no peak at all before the minor stress vanishes (docs/model3d.md):
a path whose minor stress falls to :data:`TENSION` p ends there, on the **tension cut-off**
(q_eq/p = -3 / (2 cos θ_3) on the ray, φ = 90° whatever the material), with no peak, no
friction angle and no strength ratio (NaN), rather than sitting on σ3 = 0 to ``max_strain``.

**Sizes.** A surface is at most :data:`MAX_LODE_ANGLES` rays, and its increments (rays ×
``max_strain``/``step``) and the rows of its paths' table (and their memory) are counted by the
work-size guard (:mod:`hmodel.limits`) before anything is built.

The segment's row matrix is shared by all points of a batch (:class:`hmodel.loading.control.Control`),
and here it depends on θ, so each angle is its own segment on one material point; every angle
runs on one :class:`~hmodel.rev.Rev3D` from one consolidated state.

**Fits at triaxial compression** (each one parameter, from the θ = 0 peak ratio M_c = q_eq/p),
with their π-plane envelopes r(θ) = q_eq/p at equal p (derived in docs/model3d.md):

- Mohr–Coulomb: sin φ = 3 M_c/(6 + M_c); r(θ) = 3 sin φ / (√3 sin(θ + π/3) - sin φ cos(θ + π/3));
- Matsuoka–Nakai: I1 I2 / I3 = k_MN; r solves (2 k cos 3θ/27) r³ + (1 - k/3) r² + k - 9 = 0;
- Lade–Duncan: I1³ / I3 = k_LD; r solves (2 cos 3θ/27) r³ - r²/3 + 1 - 27/k = 0;

(smallest positive root), from I1 = 3p, I2 = p² (3 - r²/3), I3 = p³ (1 - r²/3 + (2/27) r³ cos 3θ)
on the ray.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .limits import WorkTooLarge, check_count, check_memory, check_rows, steps_for, table_bytes
from .loading.named_paths import consolidate
from .loading.result import PathResult, Recorder, columns_for, lode_b
from .loading.segment import Segment, run_segment
from .params import Params
from .rev import Rev3D, Sphere
from .rev.state import equivalent_stress

#: Increments of each segment of a path (Newton's tangent starts afresh with each).
CHUNK = 200
#: Default increment of the deviatoric strain ε_s along a path.
STEP = 1e-4
#: Default largest ε_s of a path (it ends there if no peak came before).
MAX_STRAIN = 0.3
#: A path is past its peak once q_eq is this fraction below its maximum so far ...
PAST_PEAK = 0.01
#: ... and ε_s grew this much since that maximum (cell events make q_eq jump down and recover
#: within a few increments: a drop alone is no peak).
BEYOND = 0.02
#: A path is on the tension cut-off once its minor principal stress is at most this fraction of
#: p (φ within 3° of 90°): the stress cannot leave its ray further without tension.
TENSION = 1e-3
#: Most Lode angles of one surface: one a degree over [0°, 60°] (each is a path of its own, and a
#: finer π-plane shows nothing more).
MAX_LODE_ANGLES = 61
#: How a path ends with a peak (the largest q_eq of the converged states); ``max strain``: none
#: yet (a lower bound), ``tension cut-off``: none (σ3 reached 0 first).
PEAK_ENDINGS = ("past peak", "newton")

_SHIFTS = np.array([0.0, -2.0 * math.pi / 3.0, 2.0 * math.pi / 3.0])


# -- the π-plane: rays, friction angles, the three classical criteria ---------------------------

def _theta(lode_deg) -> np.ndarray:
    return np.radians(np.asarray(lode_deg, float))


def ray_direction(lode_deg) -> np.ndarray:
    """Unit deviatoric direction(s) d (..., 3) of the ray at Lode angle θ [deg] in principal
    components (1, 2, 3): d_i = sqrt(2/3) cos θ_i; the deviator on the ray is
    s = sqrt(2/3) q_eq d."""
    t = _theta(lode_deg)[..., None] + _SHIFTS
    return math.sqrt(2.0 / 3.0) * np.cos(t)


def principal_stresses(p, ratio, lode_deg) -> np.ndarray:
    """Principal stresses (..., 3) σ1 >= σ2 >= σ3 on the ray of Lode angle θ [deg] at mean
    stress p and q_eq = ratio · p: σ_i = p (1 + (2/3) ratio cos θ_i)."""
    p, r, t = np.broadcast_arrays(np.asarray(p, float), np.asarray(ratio, float), _theta(lode_deg))
    return p[..., None] * (1.0 + (2.0 / 3.0) * r[..., None] * np.cos(t[..., None] + _SHIFTS))


def friction_angle(principal) -> np.ndarray:
    """Mobilized Mohr–Coulomb friction angle [deg] of principal stresses (..., 3) (any order):
    sin φ = (σ1 - σ3)/(σ1 + σ3)."""
    s = np.sort(np.asarray(principal, float), axis=-1)
    return np.degrees(np.arcsin((s[..., 2] - s[..., 0]) / (s[..., 2] + s[..., 0])))


def phi_compression(ratio) -> np.ndarray:
    """Friction angle [deg] of a peak q_eq/p = M in triaxial compression: sin φ = 3M/(6 + M)."""
    m = np.asarray(ratio, float)
    return np.degrees(np.arcsin(np.clip(3.0 * m / (6.0 + m), -1.0, 1.0)))


def phi_extension(ratio) -> np.ndarray:
    """Friction angle [deg] of a peak q_eq/p = M in triaxial extension: sin φ = 3M/(6 - M)."""
    m = np.asarray(ratio, float)
    return np.degrees(np.arcsin(np.clip(3.0 * m / (6.0 - m), -1.0, 1.0)))


def mohr_coulomb(phi_deg, lode_deg) -> np.ndarray:
    """q_eq/p on the Mohr–Coulomb envelope (no cohesion) of friction angle φ [deg] at Lode
    angle θ [deg]: 3 sin φ / (√3 sin(θ + π/3) - sin φ cos(θ + π/3))."""
    s = np.sin(np.radians(np.asarray(phi_deg, float)))
    t = _theta(lode_deg) + math.pi / 3.0
    return 3.0 * s / (math.sqrt(3.0) * np.sin(t) - s * np.cos(t))


def _invariant_ratio(ratio, lode_deg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """I1/p, I2/p², I3/p³ on the ray of q_eq/p = ratio at Lode angle θ."""
    r = np.asarray(ratio, float)
    c3 = np.cos(3.0 * _theta(lode_deg))
    return 3.0 + 0.0 * r, 3.0 - r * r / 3.0, 1.0 - r * r / 3.0 + (2.0 / 27.0) * r ** 3 * c3


def matsuoka_nakai_k(ratio_compression) -> np.ndarray:
    """k_MN = I1 I2 / I3 of the Matsuoka–Nakai surface through q_eq/p = M_c at θ = 0
    (= (9 - sin²φ)/(1 - sin²φ) with sin φ = 3M_c/(6 + M_c))."""
    i1, i2, i3 = _invariant_ratio(ratio_compression, 0.0)
    return i1 * i2 / i3


def lade_duncan_k(ratio_compression) -> np.ndarray:
    """k_LD = I1³ / I3 of the Lade–Duncan surface through q_eq/p = M_c at θ = 0
    (= (3 - sin φ)³ / ((1 + sin φ)(1 - sin φ)²))."""
    i1, _, i3 = _invariant_ratio(ratio_compression, 0.0)
    return i1 ** 3 / i3


def _smallest_positive_root(c3, c2, c0) -> float:
    roots = np.roots([c3, c2, 0.0, c0]) if c3 != 0 else np.roots([c2, 0.0, c0])
    real = roots[np.abs(roots.imag) < 1e-9 * np.maximum(1.0, np.abs(roots))].real
    real = real[real > 0]
    if not len(real):
        raise InputError("no positive root: the surface does not close at this Lode angle")
    return float(real.min())


def matsuoka_nakai(k, lode_deg) -> np.ndarray:
    """q_eq/p on the Matsuoka–Nakai surface I1 I2 / I3 = k at Lode angle θ [deg]: the smallest
    positive root of (2k cos 3θ/27) r³ + (1 - k/3) r² + (k - 9) = 0."""
    k, c3 = np.broadcast_arrays(np.asarray(k, float), np.cos(3.0 * _theta(lode_deg)))
    out = [_smallest_positive_root(2.0 * kk * cc / 27.0, 1.0 - kk / 3.0, kk - 9.0)
           for kk, cc in zip(k.ravel(), c3.ravel())]
    return np.reshape(out, k.shape)


def lade_duncan(k, lode_deg) -> np.ndarray:
    """q_eq/p on the Lade–Duncan surface I1³ / I3 = k at Lode angle θ [deg]: the smallest
    positive root of (2 cos 3θ/27) r³ - r²/3 + (1 - 27/k) = 0."""
    k, c3 = np.broadcast_arrays(np.asarray(k, float), np.cos(3.0 * _theta(lode_deg)))
    out = [_smallest_positive_root(2.0 * cc / 27.0, -1.0 / 3.0, 1.0 - 27.0 / kk)
           for kk, cc in zip(k.ravel(), c3.ravel())]
    return np.reshape(out, k.shape)


def pi_plane_xy(ratio, lode_deg) -> np.ndarray:
    """Points (..., 2) of the π-plane (q_eq/p as radius, the compression meridian of axis 1
    up): the ray of Lode angle θ in [0°, 60°] drawn at θ from that axis."""
    t = _theta(lode_deg)
    r = np.asarray(ratio, float)
    return np.stack([r * np.sin(t), r * np.cos(t)], axis=-1)


def full_envelope(ratio_of_lode, n: int = 61) -> np.ndarray:
    """The closed π-plane curve (6(n-1), 2) of a criterion r(θ) given on [0°, 60°] (a callable
    of Lode angles in degrees), unfolded by its six-fold symmetry (isotropy: the same r at the
    three compression meridians, mirror symmetry about each)."""
    t = np.linspace(0.0, 60.0, n)
    r = np.asarray(ratio_of_lode(t), float)
    ang, rad = [], []
    for k in range(6):
        tt = t if k % 2 == 0 else t[::-1]
        rr = r if k % 2 == 0 else r[::-1]
        base = 120.0 * (k // 2) + (0.0 if k % 2 == 0 else 60.0)
        ang.append(base + (tt if k % 2 == 0 else 60.0 - tt)[:-1])
        rad.append(rr[:-1])
    a = np.radians(np.concatenate(ang))
    rad = np.concatenate(rad)
    return np.stack([rad * np.sin(a), rad * np.cos(a)], axis=-1)


# -- the driver --------------------------------------------------------------------------------

def ray_segment(p: float, lode_deg: float, strain: float, n_steps: int,
                stage: str = "ray") -> Segment:
    """The constant-p segment along the ray of Lode angle θ [deg]: ε_s grows by ``strain``
    in ``n_steps`` increments, p held at ``p``, e·σ = 0, shear strains 0 (module docstring)."""
    t = math.radians(lode_deg) + _SHIFTS
    M = np.zeros((6, 6))
    M[0, :3] = (2.0 / 3.0) * np.cos(t)
    M[1, :3] = 1.0 / 3.0
    M[2, :3] = -math.sqrt(2.0 / 3.0) * np.sin(t)
    M[3:, 3:] = np.eye(3)
    values = np.array([strain, p, 0.0, 0.0, 0.0, 0.0])
    return Segment((False, True, True, False, False, False), M, values, int(n_steps), stage)


@dataclass(frozen=True)
class FailureSurface:
    """Peaks of constant-p paths in the π-plane, and the classical criteria fitted at
    triaxial compression (:func:`failure_surface`).

    Attributes
    ----------
    p : float
        Mean stress of every path [Pa].
    lode : ndarray (N,)
        Lode angles of the paths [deg], ascending (0 is always among them: the fits need it).
    q_peak : ndarray (N,)
        Peak q_eq = sqrt(3 J2) [Pa]; NaN for a path that ended on the tension cut-off.
    ratio : ndarray (N,)
        q_peak / p.
    phi : ndarray (N,)
        Mobilized Mohr–Coulomb friction angle at the peak [deg], sin φ = (σ1 - σ3)/(σ1 + σ3);
        NaN on the tension cut-off (there σ3 = 0 and φ = 90° for any material).
    principal : ndarray (N, 3)
        σ11, σ22, σ33 at the peak [Pa] (major, intermediate, minor); on the tension cut-off,
        where the path ended.
    strain : ndarray (N, 6)
        Strain at the peak (11, 22, 33, 23, 13, 12).
    lode_reached, b_reached : ndarray (N,)
        Lode angle [deg] and b of the peak stress (the path's, to Newton's tolerance).
    ended : tuple of str
        How each path ended: ``past peak``, ``newton`` (the last converged state kept),
        ``max strain`` (no peak before ``max_strain``: ``q_peak`` is a lower bound) or
        ``tension cut-off`` (σ3 fell to :data:`TENSION` p: no peak).
    paths : PathResult
        Every state of every path (``point`` = the index of its angle; stage ``ray``).
    meta : dict
        The run's settings.
    """

    p: float
    lode: np.ndarray
    q_peak: np.ndarray
    ratio: np.ndarray
    phi: np.ndarray
    principal: np.ndarray
    strain: np.ndarray
    lode_reached: np.ndarray
    b_reached: np.ndarray
    ended: tuple[str, ...]
    paths: PathResult
    meta: dict = field(default_factory=dict)

    @property
    def peak(self) -> np.ndarray:
        """Whether each path reached its peak (ended ``past peak`` or ``newton``)."""
        return np.array([e in PEAK_ENDINGS for e in self.ended], bool)

    @property
    def ratio_compression(self) -> float:
        """M_c: the peak q_eq/p at θ = 0 (NaN where that path ended on the tension cut-off)."""
        return float(self.ratio[np.flatnonzero(self.lode == 0.0)[0]])

    @property
    def phi_compression(self) -> float:
        """Friction angle of the compression peak [deg]: sin φ = 3 M_c/(6 + M_c)."""
        return float(phi_compression(self.ratio_compression))

    @property
    def phi_extension(self) -> float | None:
        """Friction angle of the extension peak [deg] (sin φ = 3 M_e/(6 - M_e)), or None
        without a path at 60°."""
        at = np.flatnonzero(self.lode == 60.0)
        return float(phi_extension(self.ratio[at[0]])) if len(at) else None

    @property
    def strength_ratio(self) -> float | None:
        """Extension/compression strength ratio M_e/M_c of q_eq/p at equal p (None without a
        path at 60°)."""
        at = np.flatnonzero(self.lode == 60.0)
        return float(self.ratio[at[0]] / self.ratio_compression) if len(at) else None

    @property
    def k_matsuoka_nakai(self) -> float:
        return float(matsuoka_nakai_k(self.ratio_compression))

    @property
    def k_lade_duncan(self) -> float:
        return float(lade_duncan_k(self.ratio_compression))

    def fits(self, lode_deg=None) -> dict[str, np.ndarray]:
        """q_eq/p of the three criteria fitted at θ = 0, at ``lode_deg`` (default the paths'
        angles): ``mohr_coulomb``, ``matsuoka_nakai``, ``lade_duncan``."""
        t = self.lode if lode_deg is None else np.asarray(lode_deg, float)
        if not math.isfinite(self.ratio_compression):  # no compression peak: nothing to fit
            return {k: np.full(np.shape(t), math.nan) for k in ("mohr_coulomb", "matsuoka_nakai", "lade_duncan")}
        return {"mohr_coulomb": mohr_coulomb(self.phi_compression, t),
                "matsuoka_nakai": matsuoka_nakai(self.k_matsuoka_nakai, t),
                "lade_duncan": lade_duncan(self.k_lade_duncan, t)}

    def fit_strength_ratios(self) -> dict[str, float]:
        """Extension/compression ratio r(60°)/r(0°) of each fitted criterion."""
        return {k: float(v[1] / v[0]) for k, v in self.fits([0.0, 60.0]).items()}

    def table(self) -> list[dict]:
        """One row per angle: the measured peak beside the three fits (for a CSV)."""
        f = self.fits()
        return [{"lode": float(t), "q_peak": float(q), "q_p": float(r), "phi": float(ph),
                 "sig11": float(s[0]), "sig22": float(s[1]), "sig33": float(s[2]),
                 "lode_reached": float(lr), "b": float(b), "ended": e, "peak": e in PEAK_ENDINGS,
                 "mohr_coulomb": float(f["mohr_coulomb"][i]),
                 "matsuoka_nakai": float(f["matsuoka_nakai"][i]),
                 "lade_duncan": float(f["lade_duncan"][i])}
                for i, (t, q, r, ph, s, lr, b, e) in enumerate(zip(
                    self.lode, self.q_peak, self.ratio, self.phi, self.principal,
                    self.lode_reached, self.b_reached, self.ended))]


def check_lode(lode_angles) -> np.ndarray:
    """Lode angles [deg] as a sorted array with 0 added, or an InputError (each in [0, 60],
    at most :data:`MAX_LODE_ANGLES` of them)."""
    t = np.atleast_1d(np.asarray(lode_angles, float))
    if t.ndim != 1 or not len(t) or not np.all(np.isfinite(t)):
        raise InputError(f"Lode angles must be finite numbers in degrees, got {_shown(lode_angles)}")
    bad = t[(t < 0.0) | (t > 60.0)]
    if len(bad):
        raise InputError(f"a Lode angle must lie in [0, 60] degrees (0: triaxial compression, "
                         f"60: triaxial extension), got {_shown(bad.tolist())}")
    t = np.unique(np.concatenate([[0.0], t]))
    if len(t) > MAX_LODE_ANGLES:
        raise WorkTooLarge(f"{len(t)} Lode angles (with 0): at most {MAX_LODE_ANGLES}, one a degree over "
                           "[0, 60] (each angle is a path of its own)")
    return t


def _shown(values, most: int = 10) -> str:
    """``values`` for a message, the first ``most`` of a long list."""
    if isinstance(values, (list, tuple, np.ndarray)) and len(values) > most:
        return f"{list(values[:most])!r}... ({len(values)} values)"
    return repr(values)


def failure_surface(params: Params, p: float, lode_angles: Sequence[float] | float, *,
                    sphere: Sphere | None = None, solver=None, step: float = STEP,
                    max_strain: float = MAX_STRAIN, past_peak: float = PAST_PEAK,
                    beyond: float = BEYOND, compiled: bool | None = None) -> FailureSurface:
    """Drained constant-p paths from isotropic consolidation at ``p`` [Pa], one per Lode angle
    [deg] (0 added when missing), to the peak of q_eq (module docstring: the control, the
    stopping rule, the fits).

    ``step``: the increment of ε_s; ``max_strain``: the largest ε_s; ``past_peak``, ``beyond``:
    the path is past its peak once q_eq < (1 - past_peak) max q_eq and ε_s grew by ``beyond``
    since that maximum. ``sphere``, ``solver``: of the :class:`~hmodel.rev.Rev3D`;
    ``compiled``: see :func:`~hmodel.loading.segment.run_segment`.
    """
    if not (isinstance(p, (int, float, np.floating)) and math.isfinite(p) and p > 0):
        raise InputError(f"the mean stress p must be a positive number of Pa, got {p!r}")
    for name, v in (("step", step), ("max_strain", max_strain), ("past_peak", past_peak),
                    ("beyond", beyond)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive finite number, got {v!r}")
    if step >= max_strain:
        raise InputError(f"step {step} must be smaller than max_strain {max_strain}")
    lode = check_lode(lode_angles)
    n_total = steps_for(max_strain, step, f"increments of each ray (max_strain {max_strain:g} in steps of {step:g})")
    check_count(float(len(lode)) * n_total, f"increments of the failure surface ({len(lode)} rays × {n_total})")
    # the paths' table: each ray's states and its consolidated one
    rows = check_rows(float(len(lode)) * (n_total + 2), f"the failure surface's paths ({len(lode)} rays × "
                                                         f"{n_total + 2} rows)")
    check_memory(table_bytes(rows, len(columns_for(6))), f"the failure surface's paths ({rows} rows)")
    p = float(p)
    rev = Rev3D(params, sphere, solver)
    state0 = consolidate(rev, p, compiled=compiled)
    cols: list[dict] = []
    ended, peaks = [], []
    for i, theta in enumerate(lode):
        res, how = _ray(rev, state0, p, float(theta), step, n_total, past_peak, beyond, compiled)
        ended.append(how)
        ray = np.flatnonzero(res.columns["stage"] == "ray")
        k = int(ray[np.argmax(res.columns["q_eq"][ray])]) if len(ray) else 0
        peaks.append({c: v[k] for c, v in res.columns.items()})
        res.columns["point"] = np.full(len(res), i)
        cols.append(res.columns)
    paths = PathResult({c: np.concatenate([d[c] for d in cols]) for c in cols[0]},
                       {"path": "failure surface", "p": p, "lode": lode.tolist()})
    eps = np.array([[r[f"eps{c}"] for c in ("11", "22", "33", "23", "13", "12")] for r in peaks])
    sig = np.array([[r[f"sig{c}"] for c in ("11", "22", "33", "23", "13", "12")] for r in peaks])
    q = equivalent_stress(sig)
    theta_r, b = lode_b(sig)
    phi = friction_angle(sig[:, :3])
    cut = np.array([e == "tension cut-off" for e in ended])
    q, phi = np.where(cut, math.nan, q), np.where(cut, math.nan, phi)  # no peak there
    return FailureSurface(
        p=p, lode=lode, q_peak=q, ratio=q / p, phi=phi,
        principal=sig[:, :3].copy(), strain=eps, lode_reached=theta_r, b_reached=b,
        ended=tuple(ended), paths=paths,
        meta={"p": p, "lode": lode.tolist(), "step": step, "max_strain": max_strain,
              "past_peak": past_peak, "beyond": beyond, "order": rev.sphere.order,
              "n_azimuth": rev.sphere.n_azimuth, "alpha_omega": rev.sphere.alpha_omega})


def _ray(rev, state0, p, theta, step, n_total, past_peak, beyond, compiled):
    """One path of :func:`failure_surface`: segments of :data:`CHUNK` increments, each ended
    early by :class:`_PeakOrCut` (past the peak, or on the tension cut-off), until one is, or
    ``n_total`` increments, or Newton fails; its rows and how it ended."""
    rec = Recorder({"lode": theta})
    rec.record(state0, "consolidation")
    ending = _PeakOrCut(p, theta, past_peak, beyond)
    state, done, how = state0, 0, "max strain"
    while done < n_total:
        n = min(CHUNK, n_total - done)
        failures: dict = {}
        out = run_segment(rev, state, ray_segment(p, theta, n * step, n), rec, stop=ending,
                          failures=failures, compiled=compiled)
        state = out.state
        done += n
        if out.stopped is not None:
            return rec.result(), ending.how
        if failures:
            how = "newton"
            break
    return rec.result(), how


class _PeakOrCut:
    """The stop criterion of a ray (:func:`~hmodel.loading.segment.run_segment`), shown its
    states once each and in order: met past the peak (q_eq ``past_peak`` below its maximum so
    far and ε_s ``beyond`` past that maximum's) or on the tension cut-off (the minor normal
    stress at most :data:`TENSION` p); ``how`` says which came first."""

    def __init__(self, p: float, theta: float, past_peak: float, beyond: float):
        self.p, self.theta, self.past_peak, self.beyond = p, theta, past_peak, beyond
        self.top = -math.inf  # the largest q_eq so far, and ε_s there
        self.es_top = math.nan
        self.how: str | None = None

    def __call__(self, cols: dict[str, np.ndarray]) -> np.ndarray:
        q = cols["q_eq"]
        es = _eps_s(np.column_stack([cols[f"eps{c}"] for c in ("11", "22", "33")]), self.theta)
        minor = np.min([cols[f"sig{c}"] for c in ("11", "22", "33")], axis=0)
        met = np.zeros(len(q), bool)
        for i in np.flatnonzero(np.isfinite(q)):  # (NaN rows: no state there)
            if q[i] >= self.top:
                self.es_top = es[i]
            self.top = max(self.top, q[i])
            cut = minor[i] <= TENSION * self.p
            past = q[i] < (1.0 - self.past_peak) * self.top and es[i] - self.es_top > self.beyond
            if (cut or past) and self.how is None:
                self.how = "tension cut-off" if cut else "past peak"
            met[i] = cut or past
        return met


def _eps_s(eps3: np.ndarray, lode_deg: float) -> np.ndarray:
    """ε_s = (2/3) Σ_i cos θ_i ε_ii of normal strains (..., 3) on the ray of θ [deg]."""
    return (2.0 / 3.0) * eps3 @ np.cos(math.radians(lode_deg) + _SHIFTS)
