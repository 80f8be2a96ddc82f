"""Second-order work and controllability of the 3D H-model: probes of six components, the
triaxial test's d²W and the CLI's ``--test triaxial``. What the 2D and 3D analyses share (bad
input, the probe guard, the command's files) is tested for both in test_stability.py."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.loading import Program, consolidate, run_triaxial
from hmodel.rev.rev3d import Rev3D, voigt_to_tensor
from hmodel.rev.sphere import Sphere
from hmodel.stability import (
    along_program,
    along_triaxial,
    probe_directions,
    second_order_work,
    section_directions,
    strain_envelope,
    stress_envelope,
    tensor_norm,
    triaxial_directions,
)

P = Params(sliding_rhs="equilibrium")
COARSE = Sphere(order=9, n_azimuth=2)  # 38 bi-hexagons


def _elastic():
    rev = Rev3D(P, COARSE)
    s = consolidate(rev, [5e4])
    assert not s.flags.flags[..., :10].any()  # no hexagon sliding, open or with extra contacts
    return rev, s


def _contract(a, b):
    """a:b of Voigt rows by the full 3x3 tensors (not the shear weights under test)."""
    return np.einsum("...ij,...ij->...", voigt_to_tensor(a), voigt_to_tensor(b))


def test_elastic_probes_have_positive_work_equal_to_the_tangent_form():
    """d²W of every strain probe (principal and six-component) is > 0 and equals dε:D:dε, D the
    tangent by forward differences of Rev3D.step from the same state."""
    rev, s = _elastic()
    h = 1e-9
    sig = rev.step(s.select(np.zeros(6, dtype=np.int64)), h * np.eye(6)).sig
    D = (sig - s.sig[0]).T / h  # D[i, j] = dsig_i / deps_j, Voigt components
    for shear in (False, True):
        env = strain_envelope(rev, s, 40, 1e-9, shear=shear)
        assert np.all(env.work > 0) and env.min_normalized > 0
        expected = _contract(env.deps, env.deps @ D.T)
        np.testing.assert_allclose(env.work, expected, rtol=1e-4)
    assert np.abs(env.deps[:, 3:]).max() > 0.1e-9  # the six-component set probes shears


def test_probe_machinery_reduces_to_2d_and_is_a_cosine():
    # the same increment written with 3 (2D) or 6 components has the same d²W and norms
    rng = np.random.default_rng(3)
    a3, b3 = rng.normal(size=(2, 50, 3))
    a6, b6 = np.zeros((2, 50, 6))
    a6[:, [0, 1, 5]], b6[:, [0, 1, 5]] = a3, b3
    np.testing.assert_allclose(second_order_work(a6, b6)[0], second_order_work(a3, b3)[0])
    np.testing.assert_allclose(tensor_norm(a6), tensor_norm(a3))
    a6, b6 = rng.normal(size=(2, 50, 6))
    np.testing.assert_allclose(second_order_work(a6, b6)[0], _contract(a6, b6))
    np.testing.assert_allclose(tensor_norm(a6), np.sqrt(_contract(a6, a6)))
    for d in (probe_directions(30, False, 6), probe_directions(30, True, 6),
              section_directions(30, 6), triaxial_directions(31)):
        np.testing.assert_allclose(tensor_norm(d), 1.0)
    # elastic: a probe and its negative have opposite responses; stress probes invert them
    rev, s = _elastic()
    d = probe_directions(12, True, 6)
    env = strain_envelope(rev, s, 24, 1e-9, directions=np.vstack([d, -d]))
    np.testing.assert_allclose(env.dsig[12:], -env.dsig[:12], rtol=1e-5, atol=1e-8 * s.p[0])
    assert np.all(np.abs(env.normalized) <= 1 + 1e-12)
    st = stress_envelope(rev, s, 8, 1e-4)
    assert not np.isnan(st.deps).any()
    back = np.array([rev.step(s, e[None, :]).sig[0] - s.sig[0] for e in st.deps])
    np.testing.assert_allclose(back, st.dsig, rtol=1e-5, atol=1e-5 * s.p[0])
    np.testing.assert_allclose(st.dsig[:, 1], st.dsig[:, 2])  # the Rendulic plane: d22 = d33


def _sign_of_dq(ps):
    """The loading increments' d²W has the sign of dε11·dq on a triaxial path: dσ:dε =
    dσ11 dε11 (drained, σ22 = σ33 held) or dε11 (dσ11 - (dσ22 + dσ33)/2) (undrained, tr dε = 0,
    dε22 = dε33), the shear strains held."""
    sh = ps.result.stage("shear")
    r = ps.result
    start = int(np.flatnonzero(r["stage"] == "shear")[0]) - 1
    q = r["q"][start:]
    de = np.diff(r["eps11"][start:])
    dq = np.diff(q)
    big = np.abs(dq) > 1e-6 * np.abs(q).max()
    assert np.array_equal(np.sign(ps.loading_w[big]), np.sign(de * dq)[big])
    return sh["q"]


def test_drained_triaxial_loses_controllability_at_the_peak_of_q():
    params = Params(sliding_rhs="equilibrium", alpha0=math.radians(50))
    sphere = Sphere(order=9, n_azimuth=6)
    ps = along_triaxial(params, 2e5, 0.06, sphere=sphere, step=1e-3, n_probes=12, every=5)
    q = _sign_of_dq(ps)
    i = int(np.argmax(q))
    assert 0 < i < len(q) - 5  # an interior peak
    assert abs(ps.controllability - ps.shear_strain[i]) <= 1e-3 + 1e-12
    assert ps.bifurcation <= ps.controllability
    # the path is the lab test's (lab_tests.run_triaxial)
    ref = run_triaxial(params, 2e5, 0.06, sphere=sphere, step=1e-3).stage("shear")
    np.testing.assert_allclose(q, ref["q"], rtol=1e-9)


def test_undrained_triaxial_work_turns_negative_at_the_peak_of_q():
    """Loose (α0 = 65°), undrained, default rule: q peaks, then falls in the drops of cell events.
    The loading increment leaving the peak has d²W ≤ 0 and the domain is entered no later."""
    ps = along_triaxial(Params(sliding_rhs="equilibrium", alpha0=math.radians(65)), 2e5, 0.025,
                        undrained=True, step=1e-3, n_probes=12, every=5)
    q = _sign_of_dq(ps)
    i = int(np.argmax(q))
    assert 0 < i < len(q) - 1 and q[-1] < 0.9 * q[i]  # an interior peak, then softening
    # loading_w[j]: the increment into shear row j (from the consolidated state for j = 0)
    assert ps.loading_w[i + 1] <= 0 < ps.loading_w[i]
    assert ps.bifurcation <= ps.shear_strain[i]
    # the 3D default rule (the secant work) loses controllability at the peak
    assert ps.controllability_by == "secant work" and ps.controllability == ps.shear_strain[i]


def test_the_secant_rule_skips_a_recovered_drop_and_finds_a_sawtooth():
    """One-component paths (the d²W of dε11 dσ11): an isolated drop that the next increment
    makes up is skipped by both rules, one made up only after many increments by the secant
    rule; after the peak of a sawtooth (single-increment drops, stiff reloads that do not make
    them up) only the secant rule finds the loss, at the peak."""
    from hmodel.stability import _first_persistent, _first_secant_loss, loading_work

    def path(sig11):
        eps = np.zeros((len(sig11), 6))
        eps[:, 0] = np.arange(len(sig11))
        sig = np.zeros((len(sig11), 6))
        sig[:, 0] = sig11
        return eps, sig, loading_work(eps, sig)[1]
    rising = [0, 1, 2, 3, 2.9, 4, 5, 6, 7, 8, 9, 10]  # a drop at row 3, made up at once
    eps, sig, lw = path(rising)
    assert _first_secant_loss(eps, sig, lw) is None and _first_persistent(lw) is None
    slow = [0, 1, 2, 3, 1, 1.2, 1.4, 1.6, 1.8, 2, 2.2, 2.4, 2.6, 2.8, 3.2, 4]  # made up at row 14
    eps, sig, lw = path(slow)
    assert _first_secant_loss(eps, sig, lw) is None
    assert _first_secant_loss(eps, sig, lw, segment=np.arange(len(slow)) >= 10) == 3  # a new stage
    saw = [0, 2, 4, 6, 8, 6, 6.5, 7, 5, 5.5, 6, 4, 4.5, 5]  # peak at row 4
    eps, sig, lw = path(saw)
    assert _first_persistent(lw) is None and _first_secant_loss(eps, sig, lw) == 4


def test_a_3d_program_is_probed_in_six_components():
    prog = Program.from_dict({"dim": 3, "sphere": {"order": 9, "azimuths": 2}, "stage": [
        {"preset": "iso", "p": "200kPa"},
        {"name": "shear", "preset": "constant_p", "eps11": 0.01, "steps": 20}]})
    ps = along_program(prog, P, every=5, n_probes=12, shear=True)
    assert len(ps.check_step) >= 5 and np.all(np.abs(ps.check_min_w) <= 1)
    assert len(ps.loading_w) == 20


def test_triaxial_probes_are_counted_before_their_directions_are_drawn(monkeypatch):
    """Refused by the probe guard (test_stability.py), the triaxial test draws no direction."""
    import hmodel.stability as stability
    from hmodel.cell.bihex import BiHexSolver
    from hmodel.limits import WorkTooLarge

    drawn = []
    monkeypatch.setattr(stability, "triaxial_directions",
                        lambda n, shear=False: drawn.append(n) or triaxial_directions(n, shear))
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(6 * 38 * BiHexSolver().bytes_per_cell))
    with pytest.raises(WorkTooLarge):
        along_triaxial(P, 2e5, 0.002, sphere=COARSE, step=1e-3, n_probes=7)
    assert drawn == []
    along_triaxial(P, 2e5, 0.002, sphere=COARSE, step=1e-3, n_probes=6)
    assert drawn == [6]


def test_stability_command_triaxial_extension(tmp_path, cli):
    # (the files of the command, compression: test_stability.py)
    ext = tmp_path / "e"
    code, _, err = cli("stability", "--test", "triaxial", "--extension", "--undrained", "--order", "9",
                       "--azimuths", "2", "--axial-strain", "0.005", "--step", "1e-3", "--probes", "6",
                       "--out", ext)
    assert code == 0, err
    rows = (ext / "path.csv").read_text().splitlines()
    assert float(rows[-1].split(",")[2]) == pytest.approx(-0.005)  # axial strain, extension
