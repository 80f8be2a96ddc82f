"""A drained triaxial compression test of OpenSees' ``ManzariDafalias`` material (SANISAND,
Dafalias & Manzari 2004), driven through ``openseespy`` on one element: the phenomenological peer
of the KFS benchmark (``benchmarks/calibration/kfs_peer.py``).

One unit cube of 8 nodes (a ``SSPbrick``, 3 degrees of freedom per node; its single integration
point sees the homogeneous state of a laboratory specimen), symmetry planes x = 0, y = 0 and
z = 0 fixed in their normal direction. The confining pressure is nodal loads on the faces x = 1,
y = 1 and z = 1 (a quarter of the face's force on each of its four nodes). The material is
consolidated isotropically to p0 in its elastic stage (``updateMaterialStage`` 0: no plastic
flow from the zero stress it starts at, where its moduli vanish), switched to its elastoplastic
stage, and then sheared by the displacement of the top face with the lateral loads held: the
drained test of a triaxial cell.

Sign conventions: OpenSees' stresses and strains are tension positive; everything this module
returns is compression positive (hmodel's and the laboratory's): ``eps_a`` the axial strain and
``eps_v`` the volumetric strain since the end of consolidation (contraction positive), ``q`` the
deviator stress σa − σr [Pa].

The material reckons its void ratio from its total strain, e = e_init − (1 + e_init) tr ε
(compression positive), so the consolidation lowers it: a laboratory's e0 is the void ratio after
consolidation, and :func:`drained_triaxial` sets e_init so that the void ratio at the start of
shear is the test's e0 (a first consolidation measures its volumetric strain).

``openseespy`` is an optional dependency (``pip install hmodel[peer]``) that is imported when a
test is run; on machines where its shared library does not find its own bundled libraries,
:func:`reexec_with_loader_path` starts the process again with ``LD_LIBRARY_PATH`` set (the
dynamic loader reads it at process start only).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import asdict, dataclass, replace

import numpy as np

#: The atmospheric pressure the moduli and the critical state line are scaled by [Pa].
P_ATM = 101.325e3
#: Nodes of the unit cube (x, y, z).
NODES = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))
TOP = (5, 6, 7, 8)
CORNER = 7  # (1, 1, 1): its displacements are the specimen's strains (unit lengths)
MAT, ELE = 1, 1
#: Load steps of the (elastic) consolidation.
ISO_STEPS = 10
#: The material's integration (its optional arguments): OpenSees' default scheme, ModifiedEuler
#: with error control (1), with the continuum elastoplastic tangent (1: its default, the elastic
#: one, takes a Newton some 10 iterations a step), the analytic Jacobian (1) and its default
#: tolerances on the yield function and the stress.
INTEGRATION = (1, 1, 1, 1e-7, 1e-7)
#: Equilibrium tolerance of a step, as a fraction of the nodal force p0/4: the material's
#: adaptive sub-stepping makes its stress rough at about 10⁻⁵ of itself, below which a Newton
#: iteration cannot go (measured: the unbalance stalls at 2-3 N on nodal forces of 25 kN).
TOL = 1e-3
MAX_ITER = 25
#: Halvings of a step that fails before the test is given up at that strain.
MAX_HALVINGS = 6
#: The default axial strain step: at 2·10⁻⁵ a step takes one Newton iteration (most of a test's
#: time is the material's own sub-stepping, which a larger step does not save: 10⁻⁴ costs 1.5 to
#: 2.5 times as much at KFS's calibrated stiffness); q and εv agree with steps of 5·10⁻⁵ to 10⁻⁴
#: within 0.1 %.
STEP = 2e-5
#: The default spacing of the rows kept (the curve is interpolated between them).
RECORD = 1e-3


@dataclass(frozen=True)
class MDParams:
    """The parameters of OpenSees' ``ManzariDafalias`` nDMaterial (its documentation's names;
    ``e_c0`` is its ``e0``, the critical void ratio at p = 0, renamed apart from a test's e0).

    Elasticity G = G0 p_atm (2.97 − e)² / (1 + e) √(p / p_atm), K = 2(1 + ν) / (3(1 − 2ν)) G;
    critical state line e_c = e_c0 − λc (p / p_atm)^ξ, stress ratio Mc in compression and
    c Mc in extension; yield surface of radius m (in q/p); hardening h0, ch, bounding surface nb;
    dilatancy A0, nd; fabric z_max, cz (inactive in monotonic compression).
    """

    G0: float = 125.0
    nu: float = 0.05
    Mc: float = 1.25
    c: float = 0.712
    lambda_c: float = 0.019
    e_c0: float = 0.934
    ksi: float = 0.7
    m: float = 0.01
    h0: float = 7.05
    ch: float = 0.968
    nb: float = 1.1
    A0: float = 0.704
    nd: float = 3.5
    z_max: float = 4.0
    cz: float = 600.0
    p_atm: float = P_ATM

    def with_(self, **changes) -> MDParams:
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return asdict(self)

    def e_critical(self, p: float | np.ndarray) -> float | np.ndarray:
        """The critical void ratio at mean stress p [Pa]."""
        return self.e_c0 - self.lambda_c * (np.asarray(p) / self.p_atm) ** self.ksi

    def moduli(self, p: float, e: float) -> tuple[float, float]:
        """The elastic (K, G) [Pa] at mean stress p [Pa] and void ratio e."""
        g = self.G0 * self.p_atm * (2.97 - e) ** 2 / (1 + e) * math.sqrt(p / self.p_atm)
        return 2 * (1 + self.nu) / (3 * (1 - 2 * self.nu)) * g, g

    def args(self, e_init: float) -> list[float]:
        """The arguments of ``nDMaterial ManzariDafalias`` after its tag (its 18 parameters, the mass
        density 0, then :data:`INTEGRATION`)."""
        return [self.G0, self.nu, e_init, self.Mc, self.c, self.lambda_c, self.e_c0, self.ksi, self.p_atm,
                self.m, self.h0, self.ch, self.nb, self.A0, self.nd, self.z_max, self.cz, 0.0, *INTEGRATION]


@dataclass(frozen=True)
class Curve:
    """A drained test of the model at the requested axial strains (NaN beyond where it ended).

    ``completed``: it reached the last requested strain; ``reached``: the axial strain it
    reached; ``e_init``: the void ratio the material was built with (before consolidation),
    ``e_start``: its void ratio at the start of shear (the test's e0); ``e_end``, ``p_end``
    [Pa]: its void ratio and mean stress where it ended; ``steps``: the load steps taken."""

    eps_a: np.ndarray
    q: np.ndarray
    eps_v: np.ndarray
    completed: bool
    reached: float
    e_init: float
    e_start: float
    e_end: float
    p_end: float
    steps: int


def loader_path() -> str | None:
    """The folder of the libraries bundled with ``openseespy`` (None where it is not installed)."""
    import importlib.util

    spec = importlib.util.find_spec("openseespylinux")
    if spec is None or not spec.submodule_search_locations:
        return None
    return os.path.join(list(spec.submodule_search_locations)[0], "lib")


def reexec_with_loader_path(module: str) -> None:
    """Make ``openseespy`` importable: where its import fails for want of its bundled libraries
    and ``LD_LIBRARY_PATH`` does not name them yet, start this process again as
    ``python -m MODULE ARGS`` with it set (once: the variable then names them). Raises
    ImportError where openseespy is not installed."""
    try:
        import openseespy.opensees  # noqa: F401
        return
    except ImportError:
        lib = loader_path()
        current = os.environ.get("LD_LIBRARY_PATH", "")
        if lib is None or lib in current.split(os.pathsep):
            raise
    env = dict(os.environ, LD_LIBRARY_PATH=os.pathsep.join(p for p in (lib, current) if p))
    os.execve(sys.executable, [sys.executable, "-m", module, *sys.argv[1:]], env)


def _ops():
    import openseespy.opensees as ops

    ops.logFile(os.devnull, "-noEcho")  # its step-by-step warnings: the driver reports failures
    return ops


def _build(ops, params: MDParams, e_init: float, p0: float) -> None:
    """The element, the material in its elastic stage and the consolidation loads (ramped)."""
    ops.wipe()
    ops.model("basic", "-ndm", 3, "-ndf", 3)
    for tag, (x, y, z) in enumerate(NODES, start=1):
        ops.node(tag, float(x), float(y), float(z))
    for tag, (x, y, z) in enumerate(NODES, start=1):
        ops.fix(tag, int(x == 0), int(y == 0), int(z == 0))
    ops.nDMaterial("ManzariDafalias", MAT, *params.args(e_init))
    ops.element("SSPbrick", ELE, *range(1, 9), MAT)
    ops.updateMaterialStage("-material", MAT, "-stage", 0)
    ops.timeSeries("Linear", 1)
    ops.pattern("Plain", 1, 1)
    f = p0 / 4
    for tag, (x, y, z) in enumerate(NODES, start=1):
        ops.load(tag, -f * (x == 1), -f * (y == 1), -f * (z == 1))
    ops.constraints("Transformation")
    ops.numberer("Plain")
    ops.system("FullGeneral")
    ops.test("NormUnbalance", TOL * f, MAX_ITER)
    ops.algorithm("Newton")
    ops.integrator("LoadControl", 1.0 / ISO_STEPS)
    ops.analysis("Static")


def _consolidate(ops, params: MDParams, e0: float, p0: float) -> float:
    """Build and consolidate with the void ratio e0 at the end of consolidation; returns the
    material's e_init that gives it."""
    e_init = e0
    for _ in range(4):  # each pass starts from the void ratio the last one implies
        _build(ops, params, e_init, p0)
        if ops.analyze(ISO_STEPS) != 0:
            raise RuntimeError(f"consolidation to {p0:g} Pa failed")
        ev = -sum(ops.nodeDisp(CORNER))
        want = (e0 + ev) / (1 - ev)
        if abs(want - e_init) < 1e-7:
            break
        e_init = want
    return e_init


def _state(ops, u0) -> tuple[float, float, float, float, float]:
    """eps_a, q, eps_v (compression positive, since the end of consolidation), p [Pa] and the
    material's void ratio."""
    u = ops.nodeDisp(CORNER)
    ea = -(u[2] - u0[2])
    ev = -sum(u[i] - u0[i] for i in range(3))
    s = ops.eleResponse(ELE, "stresses")
    q = -s[2] + 0.5 * (s[0] + s[1])
    p = -(s[0] + s[1] + s[2]) / 3
    return ea, q, ev, p, ops.eleResponse(ELE, "state")[24]


def drained_triaxial(params: MDParams, p0: float, e0: float, strains, step: float = STEP,
                     record: float = RECORD, max_failures: int | None = None) -> Curve:
    """A drained triaxial compression test after isotropic consolidation to p0 [Pa] with the
    void ratio e0 there, sheared to the last of ``strains`` (axial strains, increasing, >= 0) in
    steps of ``step`` (halved where one fails, up to :data:`MAX_HALVINGS` times, and widened
    again after two that pass), its state kept every ``record`` and interpolated at
    ``strains``. ``max_failures``: the test ends after that many failed steps (a calibration's
    bound on the parameter sets whose steps keep failing: each failed step sub-steps the material
    down to its least sub-step, and such a test costs 10 to 20 times one that passes)."""
    strains = np.asarray(strains, float)
    ops = _ops()
    e_init = _consolidate(ops, params, e0, p0)
    ops.updateMaterialStage("-material", MAT, "-stage", 1)
    ops.loadConst("-time", 0.0)
    u0 = ops.nodeDisp(CORNER)
    end = float(strains[-1])
    # The top face's displacement follows the time: uz = uz0 - t (t the axial strain).
    ops.timeSeries("Path", 2, "-time", 0.0, 1.0, "-values", u0[2], u0[2] - 1.0)
    ops.pattern("Plain", 2, 2)
    for tag in TOP:
        ops.sp(tag, 3, 1.0)
    ops.analysis("Static")
    # A step of no strain commits the stage's switch: the material computes its moduli at commit,
    # and until then keeps those of the elastic stage (at p_atm).
    ops.integrator("LoadControl", 0.0)
    if ops.analyze(1) != 0:
        raise RuntimeError("the switch to the elastoplastic stage failed")
    rows = [(0.0, 0.0, 0.0, *_state(ops, u0)[3:])]
    t, steps, halvings, passed, failures, stuck = 0.0, 0, 0, 0, 0, False
    for target in [*np.arange(record, end - 1e-12, record), end]:
        while t < target - 1e-12 and not stuck:
            if halvings == 0:  # whole steps to the target in one call
                n = max(1, math.ceil((target - t) / step - 1e-9))
                ops.integrator("LoadControl", (target - t) / n)
                failed = ops.analyze(n) != 0
            else:
                ops.integrator("LoadControl", min(step / 2 ** halvings, target - t))
                failed = ops.analyze(1) != 0
            done = ops.getTime()  # a failed call keeps the steps before the failing one
            steps += round((done - t) / (step / 2 ** halvings))
            t = done
            if failed:
                failures += 1
                stuck = halvings == MAX_HALVINGS or (max_failures is not None and failures > max_failures)
                halvings, passed = min(halvings + 1, MAX_HALVINGS), 0
            elif halvings:
                passed += 1
                if passed == 2:
                    halvings, passed = halvings - 1, 0
        rows.append(_state(ops, u0))
        if stuck:
            break
    ops.wipe()
    r = np.array(rows)
    reached = float(r[-1, 0])
    ok = strains <= reached + 1e-9
    q, ev = np.full(len(strains), np.nan), np.full(len(strains), np.nan)
    q[ok] = np.interp(strains[ok], r[:, 0], r[:, 1])
    ev[ok] = np.interp(strains[ok], r[:, 0], r[:, 2])
    return Curve(strains, q, ev, bool(ok.all()), reached, float(e_init), float(r[0, 4]), float(r[-1, 4]),
                 float(r[-1, 3]), steps)
