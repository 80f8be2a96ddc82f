"""Cell networks over a range of materials (family networks): the training domain
stored in the model file and checked at run time, kn and r scaled out, materials drawn per path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import CellState, ClosedFormSolver
from hmodel.cli.app import main
from hmodel.errors import InputError
from hmodel.surrogate.formulations.registry import make_formulation
from hmodel.surrogate.model import Architecture, Surrogate
from hmodel.surrogate.modelfile import ModelFileError, load, save
from hmodel.surrogate.scalers import Affine
from hmodel.surrogate.solver import SurrogateSolver

DOMAIN = {"kt_kn": [0.2, 1.0], "phi_g": [10.0, 45.0], "alpha0": [35.0, 75.0]}


def tiny_family(domain: dict | None = DOMAIN, seed: int = 0) -> Surrogate:
    """A small compliance network of the family's inputs (untrained weights: the domain and
    its checks are what is tested here, not the response)."""
    form = make_formulation("compliance", Params(), family=True)
    rng = np.random.default_rng(seed)
    n_in, width = 4 + len(form.material_inputs), 8
    weights = [(rng.normal(size=(width, n_in)) * 0.1, np.zeros(width)),
               (rng.normal(size=(24, width)) * 0.1, np.zeros(24))]
    meta = {"params": Params().to_dict()} | ({"domain": domain} if domain else {})
    return Surrogate(form, Architecture(width, 1, "silu"), Affine("zscore", np.zeros(n_in), np.ones(n_in)),
                     Affine("zscore", np.zeros(24), np.ones(24)), weights, meta)


def test_domain_is_stored_and_read_in_params_units(tmp_path):
    path = save(tiny_family(), tmp_path / "fam.safetensors")
    m = load(path)
    assert m.formulation.material_inputs == ("kt_kn", "tan_phi_g")
    d = SurrogateSolver(m).domain
    assert d["kt_kn"] == (0.2, 1.0)
    assert d["phi_g"] == pytest.approx((math.radians(10), math.radians(45)))  # as params.phi_g
    assert d["alpha0"] == pytest.approx((math.radians(35), math.radians(75)))


def test_inside_accepted_outside_refused_in_one_line(tmp_path):
    s = SurrogateSolver(load(save(tiny_family(), tmp_path / "fam.safetensors")))
    # any kn and r (scaled out), any material inside the domain, its edges included
    for p in (Params(kn=3e6, radius=0.01, kt_kn=0.2, phi_g=math.radians(45.0), alpha0=math.radians(35.0)),
              Params(kn=5e9, kt_kn=1.0, phi_g=math.radians(10.0), alpha0=math.radians(75.0))):
        s.check(p)
    with pytest.raises(InputError) as e:
        s.check(Params(phi_g=math.radians(50.0)))
    msg = str(e.value)
    assert "outside the model's training domain: phi_g=50 (trained 10–45)" in msg and "\n" not in msg
    with pytest.raises(InputError, match="kt_kn=0.1 .trained 0.2–1."):
        s.check(Params(kt_kn=0.1))
    with pytest.raises(InputError, match="alpha0=80"):
        s.check(Params(alpha0=math.radians(80.0)))
    # what the domain does not span is the trained material's, as for one material
    with pytest.raises(InputError, match="trained for other material parameters: g2"):
        s.check(Params(g2=1))


def test_single_material_model_has_no_domain_and_refuses_other_materials():
    from hmodel.surrogate.shipped import load_shipped

    s = SurrogateSolver(load_shipped("default"))
    assert s.domain is None
    s.check(Params())
    for other in (Params(kn=3e8), Params(phi_g=math.radians(25.0))):
        with pytest.raises(InputError, match="trained for other material parameters"):
            s.check(other)


def test_family_file_without_domain_is_refused_at_load(tmp_path):
    path = save(tiny_family(domain=None), tmp_path / "nodomain.safetensors")
    with pytest.raises(ModelFileError) as e:
        load(path)
    assert "needs its training domain" in str(e.value) and "\n" not in str(e.value)


def test_cli_refuses_a_material_outside_the_domain(tmp_path, capsys):
    path = save(tiny_family(), tmp_path / "fam.safetensors")
    out = tmp_path / "run"
    code = main(["run", "biaxial", "--solver", f"surrogate:{path}", "-p", "phi_g=50", "-p", "n_theta=12",
                 "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 1 and not out.exists()
    assert err.startswith("hmodel: error:") and "outside the model's training domain" in err
    assert err.count("\n") == 1


def test_family_features_scale_out_kn_and_r():
    """The network sees N/(kn 2r), T/(kn 2r), d/2r and the material's kt/kn, tan(phi_g)."""
    form = make_formulation("compliance", Params(), family=True)
    cf = ClosedFormSolver()
    a, b = Params(kn=1e8, radius=1.0, kt_kn=0.4), Params(kn=7e9, radius=0.003, kt_kn=0.4)
    Xs = []
    for p in (a, b):
        st, _ = cf.step(p, cf.initial(p, (1,)), -1e-3 * p.l10, -5e-4 * p.l20)
        Xs.append(form.features(st.values, p))
    np.testing.assert_allclose(Xs[0], Xs[1], rtol=1e-9)
    np.testing.assert_allclose(Xs[0][0, 4:], [0.4, math.tan(a.phi_g)])


@pytest.mark.parametrize("kt_kn, phi_g", [(0.5, 30.0), (0.25, 15.0)])
def test_closed_form_cell_is_invariant_under_kn_and_r(kt_kn, phi_g):
    """Eq. 1.7 is homogeneous: forces scale with kn (eqs. 1.3, 1.8-1.9) and all lengths with r
    (eq. 1.2 with d = 2r), so after the same cell strains N/(kn 2r), T/(kn 2r), lengths/2r and the
    angle are the same at any kn and r (hand argument, checked here on a path that slides)."""
    cf = ClosedFormSolver()
    runs = []
    for kn, r in ((2e8, 1.0), (3.7e6, 1.0), (2e8, 0.004), (9e9, 25.0)):
        p = Params(kn=kn, radius=r, kt_kn=kt_kn, phi_g=math.radians(phi_g))
        st = cf.initial(p, (3,))
        theta = np.array([0.3, 1.0, -0.5])  # compressions; l1 shortened, l2 lengthened (slides)
        dl1, dl2 = -p.l10 * 2e-4 * np.cos(theta), -p.l20 * 2e-4 * np.sin(theta)
        sliding = False
        for _ in range(40):
            st, f = cf.step(p, st, dl1, dl2)
            sliding |= bool(f.flags[..., 0].any())
        v = st.values
        F, d = kn * 2 * r, 2 * r
        runs.append(np.column_stack([v[:, 0] / d, v[:, 1] / d, v[:, 2], v[:, 3] / F, v[:, 4] / F,
                                     v[:, 5] / F, v[:, 6] / d, v[:, 7] / d]))
    assert sliding  # the Coulomb bound (tan phi_g N, kn-free in these units) was reached
    for other in runs[1:]:
        np.testing.assert_allclose(other, runs[0], rtol=1e-9, atol=1e-14)


def test_dataset_draws_one_material_per_path(tmp_path):
    """Each path's kt/kn and phi_g are uniform draws in the ranges, the same whatever the shard
    size, recorded on its rows; and each row is eq. 1.7 of that material (closed form rerun)."""
    from hmodel.data import DatasetSpec, generate
    from hmodel.data.schema import MATERIAL_COLUMNS

    spec = DatasetSpec(kind=2, n_directions=3, theta_min=-60.0, theta_max=150.0, alpha0_min=40.0,
                       alpha0_max=60.0, alpha0_step=20.0, max_strain=0.004, step=0.001, start_every=0.002,
                       magnitude=0.002, magnitude_min=0.0, n_increments=4, substeps=1,
                       kt_kn_range="0.2:1", phi_g_range="10:45")
    params = Params()
    c = generate(spec, params, tmp_path / "a").read()
    other = generate(DatasetSpec(**{**spec.to_dict(), "shard_rows": 10}), params, tmp_path / "b").read()
    assert set(MATERIAL_COLUMNS) <= set(c)
    for k in MATERIAL_COLUMNS:
        np.testing.assert_array_equal(c[k], other[k])
    assert np.all((c["kt_kn"] >= 0.2) & (c["kt_kn"] <= 1.0))
    assert np.all((c["phi_g"] >= math.radians(10)) & (c["phi_g"] <= math.radians(45)))
    paths = np.unique(c["path_id"])
    per_path = {p: np.unique(c["kt_kn"][c["path_id"] == p]) for p in paths}
    assert all(len(v) == 1 for v in per_path.values()) and len({float(v[0]) for v in per_path.values()}) == len(paths)
    cf = ClosedFormSolver()
    for i in (0, len(c["deps1"]) // 2, len(c["deps1"]) - 1):
        m = params.with_(kt_kn=float(c["kt_kn"][i]), phi_g=float(c["phi_g"][i]))
        before = np.array([[c[k][i] for k in ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")]])
        l10, l20 = m.with_(alpha0=float(c["alpha0"][i])).l10, m.with_(alpha0=float(c["alpha0"][i])).l20
        after, _ = cf.step(m, CellState(before), -l10 * c["deps1"][i], -l20 * c["deps2"][i])
        np.testing.assert_allclose(after.values[0, [2, 3, 4, 5]],
                                   [c["alpha_next"][i], c["N1_next"][i], c["N2_next"][i], c["T1_next"][i]],
                                   rtol=1e-10, atol=1e-9)


def test_meso_family_takes_the_runs_geometry_and_material():
    """A richer family network's cell is the run's: the hexagon-center cell's free grain at the
    run's alpha0 has the touching radius sqrt(1 + 4 sin^2 alpha0) - 1 (r = 1; hand geometry:
    grain 2 at (d2/2, l2/2) with d = 2, l2 = 4 sin alpha0), and the inputs end with the material."""
    form = make_formulation("meso", Params(sliding_rhs="equilibrium"), "dem:hexagon-center", family=True)
    assert form.material_inputs == ("kt_kn", "tan_phi_g", "alpha0")
    for a0 in (38.0, 55.0):
        p = Params(alpha0=math.radians(a0), kt_kn=0.3, phi_g=math.radians(20.0), sliding_rhs="equilibrium")
        f = form.for_material(p)
        assert f._cage[0] == pytest.approx(math.sqrt(1 + 4 * math.sin(p.alpha0) ** 2) - 1, rel=1e-12)
        v = form.initial(p, (2,)).values
        assert v[0, 2] == pytest.approx(p.alpha0)  # the unloaded cell opens at the run's alpha0
        X = form.features(v, p)
        np.testing.assert_allclose(X[:, -3:], [[0.3, math.tan(p.phi_g), p.alpha0]] * 2)


def test_family_rollout_steps_each_window_with_its_own_material():
    """Rollout training of a family: windows of two materials, stepped together (torch, each
    window's material inputs, Coulomb bound and cage), charge the error that each material's
    own formulation (the REV's: :meth:`for_material`) gives stepping its windows alone (NumPy)."""
    import torch

    from hmodel.surrogate.model import Architecture
    from hmodel.surrogate.training import build_network

    base = Params(sliding_rhs="equilibrium")
    form = make_formulation("meso", base, "dem:hexagon-center", family=True)
    mats = [base.with_(kt_kn=0.3, phi_g=math.radians(15.0), alpha0=math.radians(40.0)),
            base.with_(kt_kn=0.9, phi_g=math.radians(40.0), alpha0=math.radians(57.0))]
    rng = np.random.default_rng(5)
    n, T, sub = 12, 3, 2
    which = np.arange(n) % 2
    rows = {"kt_kn": np.array([mats[j].kt_kn for j in which]), "phi_g": np.array([mats[j].phi_g for j in which]),
            "alpha0": np.array([mats[j].alpha0 for j in which])}
    material = form._window_materials(rows, np.arange(n))
    assert material["cage"][0, 0] != material["cage"][1, 0]  # the free grain's reach follows alpha0
    F, d = form.force_scale, 2 * base.radius
    l0 = np.array([[mats[j].l10, mats[j].l20] for j in which])
    z0 = np.zeros((n, 11))
    z0[:, 2] = rows["alpha0"] + rng.normal(0, 0.01, n)
    z0[:, 6:8] = l0 * (1 - 1e-3)
    z0[:, 3:6] = F * rng.uniform(0, 2e-4, (n, 3)) * [1, 1, 0.3]
    z0[:, 8:10] = F * d * rng.uniform(0, 1e-3, (n, 2))
    e = rng.normal(0, 1, (n, T, 2))
    dl = -l0[:, None, :] * e * form.m0
    target = form._learned_values(z0)[:, None, :] + rng.normal(0, 1, (n, T, 6)) * form._scales() * form.m0 * 0.1
    mask = np.ones((n, T))
    torch.manual_seed(0)
    net = build_network(Architecture(16, 2, "silu"), 11, form.n_outputs).double()
    X0 = np.vstack([form.features(z0[which == j], mats[j]) for j in (0, 1)])
    off, scale = X0.mean(0), X0.std(0) + 1e-9
    t = lambda a: torch.as_tensor(a, dtype=torch.float64)  # noqa: E731
    with torch.no_grad():
        got = float(form.rollout_error(net.float(), *(t(a) for a in (z0, e, dl, target, mask)),
                                       lambda X: (X - t(off)) / t(scale), sub, {k: t(v) for k, v in material.items()}))
    want = 0.0
    for j, m in enumerate(mats):
        f, rows_j = form.for_material(m), which == j
        z = z0[rows_j]
        for k in range(T):
            for _ in range(sub):
                with torch.no_grad():
                    X = torch.as_tensor((form.features(z, m) - off) / scale, dtype=torch.float32)
                    out = net(X).double().numpy()
                z, _ = f.advance(z, f.head(out, e[rows_j, k] / sub), dl[rows_j, k] / sub)
            err = (f._learned_values(z) - target[rows_j, k]) / (f._scales() * f.m0)
            want += ((err ** 2).mean(1)).sum()
    assert got == pytest.approx(want / mask.sum(), rel=1e-6)
    # the check can fail: one material's bound and cage for every window give another error
    with torch.no_grad():
        one = dict(material, tan_phi=np.full(n, mats[0].tan_phi), cage=np.tile(form.for_material(mats[0])._cage, (n, 1)))
        other = float(form.rollout_error(net.float(), *(t(a) for a in (z0, e, dl, target, mask)),
                                         lambda X: (X - t(off)) / t(scale), sub, {k: t(v) for k, v in one.items()}))
    assert other != pytest.approx(got, rel=1e-6)


def test_shipped_family_reproduces_the_closed_form_at_an_unseen_material():
    """The shipped standard-cell family network at a material that is no training path's (those
    are continuous random draws), on a short drained path through the peak's onset: within 1 %
    of peak q of the closed form (rows matched stage by stage), at a kn and r of its own."""
    from hmodel.compare import deviations
    from hmodel.loading import run_biaxial
    from hmodel.surrogate.solver import load_solver

    solver = load_solver("surrogate:family")
    assert solver.domain is not None
    p = Params(kt_kn=0.37, phi_g=math.radians(23.3), alpha0=math.radians(52.1), kn=7e7, radius=0.002,
               n_theta=36)
    ref = run_biaxial(p, [200e3], 0.02, step=1e-3)
    ann = run_biaxial(p, [200e3], 0.02, step=1e-3, solver=solver)
    d = deviations(ref, ann)[0]
    assert d["rows"] > 20 and d["q_max_dev_rel"] < 0.01 and d["eps_v_max_dev"] < 1e-3


def test_a_family_steps_many_sets_in_one_network_call():
    """A family network steps the cells of several parameter sets together (a calibration's
    sets; one network call per sub-step) to what each set's own :meth:`step` gives, each set
    with its own sub-steps, Coulomb bound and cage; the REV of many sets takes that path."""
    from hmodel.rev import Rev

    base = Params(sliding_rhs="equilibrium", n_theta=6)
    form = make_formulation("meso", base, "dem:hexagon-center", mechanisms=2, cell_step=2.5e-4, family=True)
    n_in = len(form.input_names) + len(form.material_inputs)
    rng = np.random.default_rng(3)
    width = 12
    weights = [(rng.normal(size=(width, n_in)) * 0.3, rng.normal(size=width) * 0.1),
               (rng.normal(size=(form.n_outputs, width)) * 0.3, rng.normal(size=form.n_outputs) * 0.1)]
    meta = {"params": base.to_dict(), "domain": {"kt_kn": [0.2, 1.0], "phi_g": [10.0, 45.0], "alpha0": [35.0, 60.0]}}
    model = Surrogate(form, Architecture(width, 1, "silu"), Affine("zscore", np.zeros(n_in), np.ones(n_in)),
                      Affine("zscore", np.zeros(form.n_outputs), np.ones(form.n_outputs)), weights, meta)
    sets = [base.with_(kt_kn=0.3, phi_g=math.radians(15.0), alpha0=math.radians(40.0)),
            base.with_(kt_kn=0.9, phi_g=math.radians(40.0), alpha0=math.radians(57.0)),
            base.with_(kt_kn=0.5, phi_g=math.radians(25.0), alpha0=math.radians(47.0))]
    index = np.array([0, 1, 2, 1])
    C = 5
    v = np.stack([form.initial(sets[k], (C,)).values for k in index])
    v[..., 3:6] = form.force_scale * rng.uniform(0, 2e-4, (len(index), C, 3)) * [1, 1, 0.3]
    v[..., 8:10] = form.force_scale * 2 * rng.uniform(0, 1e-3, (len(index), C, 2))
    # the second set's points take three sub-steps, the others one or two
    scale = np.array([1.0, 3.5, 1.75, 3.5])[:, None] * 2e-4
    dl1 = -np.array([sets[k].l10 for k in index])[:, None] * scale * rng.uniform(0.5, 1.0, (len(index), C))
    dl2 = np.array([sets[k].l20 for k in index])[:, None] * scale * rng.uniform(-1.0, 1.0, (len(index), C))
    together = SurrogateSolver(model)
    got, flags = together.step_sets(sets, index, CellState(v), dl1, dl2)
    alone = SurrogateSolver(model)
    for b, k in enumerate(index):
        want, wflags = alone.step(sets[k], CellState(v[b]), dl1[b], dl2[b])
        np.testing.assert_allclose(got[b], want.values, rtol=1e-6, atol=1e-9 * form.force_scale)
        np.testing.assert_array_equal(flags[b], wflags.flags)
    assert together.counts["substeps"] == 1 + 3 + 2 and alone.counts["substeps"] == 1 + 3 + 2 + 3
    # the check can fail: the sets' materials swapped give other states
    swapped, _ = SurrogateSolver(model).step_sets(sets[::-1], index, CellState(v), dl1, dl2)
    assert not np.allclose(swapped, got, rtol=1e-6)
    # a REV of many sets steps them in one call per sub-step
    rev = Rev(sets, SurrogateSolver(model))
    assert rev.solver.batches_sets
    calls = []
    rev.solver.step_sets = lambda *a, _f=rev.solver.step_sets: calls.append(1) or _f(*a)
    rev.step(rev.initial(3), np.array([[-1e-4, 0.5e-4, 0.0]] * 3))
    assert calls == [1]


def test_shipped_richer_family_follows_the_dem_rev_at_an_unseen_material():
    """The shipped hexagon-center family network, without YADE, at a material none of its
    training loadings had (set 1 of benchmarks/dem/dem_ann_family.py, drawn after training),
    against the DEM-REV's curves of that material (tests/data): max |Δq| / peak q over the shear
    stage to 2 % within a bound above the benchmark's figure there (docs: DEM cells, the family);
    outside its domain the run is refused."""
    import csv
    from dataclasses import replace
    from pathlib import Path

    from hmodel.compare import run_path, standard_paths
    from hmodel.surrogate.solver import load_solver

    rows = list(csv.DictReader(open(Path(__file__).parent / "data" / "hexagon-center-family_dem-rev_set1.csv")))
    p = Params(sliding_rhs="equilibrium", n_theta=12, kt_kn=0.7464036984223774,
               phi_g=math.radians(27.887832032475814), alpha0=math.radians(45.084650187866664))
    paths = {s.name: s for s in standard_paths(0.02)}
    solver = load_solver("surrogate:hexagon-center-family")

    def shear(eps11, q):  # the shear stage: from the last isotropic row (q = 0) on
        start = np.flatnonzero(np.abs(q) < 1e-6 * np.abs(q).max())[-1]
        return eps11[start:] - eps11[start], q[start:]

    # the stage-2 network (before the long rollouts) missed by 6.4 and 2.3 %: these bounds fail it
    for spec, bound in ((replace(paths["drained"], p0=(1e5,)), 0.04), (paths["undrained"], 0.02)):
        dem = np.array([[float(r["eps11"]), float(r["q_kPa"]) * 1e3] for r in rows if r["path"] == spec.name])
        e_dem, q_dem = shear(dem[:, 0], dem[:, 1])
        res, _ = run_path(p, spec, solver, 1e-3, 2e-4)
        e_ann, q_ann = shear(res.point(0)["eps11"], res.point(0)["q"])
        assert e_ann[-1] == pytest.approx(0.02, rel=1e-6) and len(e_dem) > 15
        dev = np.max(np.abs(np.interp(e_dem, e_ann, q_ann) - q_dem)) / q_dem.max()
        assert dev < bound, (spec.name, dev)
    with pytest.raises(InputError, match="training domain"):
        run_path(p.with_(kt_kn=1.5), paths["undrained"], solver, 1e-3, 2e-4)


def test_a_compliance_family_of_many_sets_steps_each_set_as_before():
    """The standard cell's family (a compliance network, which has no many-material step) runs
    a REV of several sets one set at a time, as before the meso family's batched step."""
    from hmodel.rev import Rev
    from hmodel.surrogate.solver import load_solver

    sets = [Params(n_theta=6, kt_kn=0.3), Params(n_theta=6, kt_kn=0.6)]
    solver = load_solver("surrogate:family")
    assert not solver.batches_sets
    deps = np.array([[-1e-4, 0.5e-4, 0.0]] * 2)
    both = Rev(sets, solver).step(Rev(sets, solver).initial(2), deps)
    for k, p in enumerate(sets):
        one = Rev(p, load_solver("surrogate:family"))
        np.testing.assert_allclose(both.sig[k], one.step(one.initial(1), deps[:1]).sig[0], rtol=1e-12)
