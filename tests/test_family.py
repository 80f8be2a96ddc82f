"""Cell networks over a range of materials (family networks, issue 36): the training domain
stored in the model file and checked at run time, kn and r scaled out, materials drawn per path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import ClosedFormSolver
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
