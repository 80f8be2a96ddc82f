"""An ensemble of compliance networks: averaged compliances, its disagreement as the gate's trust
score, and active learning with it."""

import json

import numpy as np
import pytest

from hmodel import InputError, Params
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.compare import run_path
from hmodel.loading import standard_paths
from hmodel.surrogate import modelfile
from hmodel.surrogate.solver import SurrogateSolver
from hmodel.surrogate.training import TrainConfig, train
from hmodel.surrogate.training_rows import params_of, read_sample
from hmodel.surrogate.gate import DisagreementGate, disagreement
from hmodel.surrogate.trust import fit_ensemble_trust

PARAMS = Params(n_theta=12)


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory, small_sample):
    """Three compliance networks trained on the small sample (tests/conftest.py) with the
    ensemble's trust: their folder (m0-m2.safetensors), the members and the trust's table."""
    root = tmp_path_factory.mktemp("ens")
    cols, info = read_sample(small_sample, "train")
    members = []
    for seed in (0, 1, 2):
        m, _ = train(cols, params_of(info), TrainConfig(formulation="compliance", width=16, depth=2, epochs=15,
                                                        seed=seed, device="cpu"))
        m.meta["params"] = info["params"]
        members.append(m)
    trusted, table = fit_ensemble_trust(members, read_sample(small_sample, "test")[0])
    for k, m in enumerate(trusted):
        modelfile.save(m, root / f"m{k}.safetensors")
    return root, trusted, table


def test_disagreement_is_the_members_spread():
    a, b = np.array([[1.0, 2.0], [0.0, 0.0]]), np.array([[3.0, 2.0], [0.0, 4.0]])
    # member std per output: row 0 (1, 0), row 1 (0, 2); in units of the scales (1, 2)
    np.testing.assert_allclose(disagreement([a, b], np.array([1.0, 2.0])), [np.sqrt(0.5), np.sqrt(0.5)])
    assert np.all(disagreement([a, a], np.ones(2)) == 0.0)


def test_the_ensemble_averages_compliances_and_ranks_its_errors(ensemble, small_sample):
    _, members, table = ensemble
    t = members[0].meta["trust"]
    assert t["kind"] == "ensemble" and len(t["members"]) == 3 and members[0].trust_reference is None
    # it ranks the held-out errors: a score unrelated to them has Spearman ~0 and its least
    # trusted 10 % hold ~10 % of the error (measured here: 0.68 and 31 %)
    assert table[-1]["top_fraction"] == 0.1
    assert table[0]["spearman"] > 0.3 and table[-1]["share_of_error"] > 0.2
    # identical members: the ensemble is that network, and it agrees with itself everywhere
    spec = [s for s in standard_paths(0.01) if s.name == "drained"][0]
    one, _ = run_path(PARAMS, spec, SurrogateSolver(members[1]), 2e-3, 1e-3)
    two, _ = run_path(PARAMS, spec, SurrogateSolver([members[1], members[1]]), 2e-3, 1e-3)
    np.testing.assert_array_equal(one.point(0)["q"], two.point(0)["q"])
    # the held-out scores it stores are the spread of the members' own increments of those rows
    held = read_sample(small_sample, "test")[0]
    f = members[0].formulation
    names = ("alpha_next", "N1_next", "N2_next", "T1_next")
    before = np.column_stack([held[k[:-5]] for k in names])
    inc = [np.column_stack([m.predict(held)[k] for k in names]) - before for m in members]
    s = disagreement(inc, np.asarray(t["increment_scale"]))
    levels, q = t["quantiles"]["levels"], t["quantiles"]["scores"]
    # (stored from the networks' float32 inference, recomputed here through predict's float64)
    assert np.quantile(s, 0.9) == pytest.approx(np.interp(0.9, levels, q), rel=1e-6) and f.name == "compliance"


def test_a_gate_that_holds_every_cell_is_the_closed_form(ensemble):
    _, members, _ = ensemble
    spec = [s for s in standard_paths(0.01) if s.name == "drained"][0]
    ref, _ = run_path(PARAMS, spec, "closed-form", 2e-3, 1e-3)
    gated = SurrogateSolver(members, gate=0.5, fallback=ClosedFormSolver())
    assert isinstance(gated.gate, DisagreementGate) and gated.gate.per_increment
    gated.gate.threshold = -1.0  # below any spread: every cell to the closed form
    res, _ = run_path(PARAMS, spec, gated, 2e-3, 1e-3)
    assert gated.counts["gated"] == gated.counts["gate_checked"] > 0
    assert gated.fractions(PARAMS, gated.initial(PARAMS, (12,))) == {}  # decided per increment
    np.testing.assert_allclose(res.point(0)["q"], ref.point(0)["q"], rtol=1e-7)  # Newton tolerance


def test_the_gate_refuses_other_members_or_no_disagreement(ensemble):
    _, members, _ = ensemble
    with pytest.raises(InputError, match="in the order"):
        SurrogateSolver([members[0], members[2], members[1]], gate=0.9, fallback=ClosedFormSolver())
    with pytest.raises(InputError, match="trust"):  # members[1] holds no trust at all
        SurrogateSolver([members[1], members[2]], gate=0.9, fallback=ClosedFormSolver())


def test_cli_trust_and_refine_of_an_ensemble(ensemble, small_sample, tmp_path, capsys):
    from hmodel.cli.app import main

    root, _, _ = ensemble
    m = [str(root / f"m{k}.safetensors") for k in range(3)]
    plain = [modelfile.load(p) for p in m]
    for k, p in enumerate(plain):  # the members without the ensemble's trust
        p.meta.pop("trust", None)
        modelfile.save(p, tmp_path / f"p{k}.safetensors")
    assert main(["surrogate", "trust", "+".join(str(tmp_path / f"p{k}.safetensors") for k in range(3)),
                 str(small_sample), "--out", str(tmp_path / "t0.safetensors")]) == 0
    assert "surrogate:" in capsys.readouterr().out
    assert modelfile.load(tmp_path / "t0.safetensors").meta["trust"]["kind"] == "ensemble"
    out = tmp_path / "al"
    assert main(["surrogate", "refine", "+".join([str(tmp_path / "t0.safetensors")] + m[1:]), "--data",
                 str(small_sample), "--out", str(out), "--rounds", "1", "--gate", "0.05", "--states", "20",
                 "--increments", "4", "--epochs", "2", "--paths", "drained", "--axial-strain", "0.01",
                 "--step", "2e-3", "--iso-step", "1e-3", "-p", "n_theta=12"]) == 0
    summary = json.loads((out / "round-1" / "summary.json").read_text())["summary"]
    assert summary["rows_added"] > 0
    final = [modelfile.load(out / n) for n in ("model.safetensors", "model-1.safetensors", "model-2.safetensors")]
    assert final[0].meta["trust"]["kind"] == "ensemble"
    SurrogateSolver(final, gate=0.5, fallback=ClosedFormSolver())  # the refitted trust fits the new members


def test_the_shipped_ensemble_gates_on_its_disagreement():
    """``--solver surrogate:ensemble``: the default network and two more of its recipe, whose
    trust is their disagreement, with a fresh install's files only."""
    from hmodel.solvers import get_solver
    from hmodel.surrogate.shipped import load_shipped
    from hmodel.surrogate.solver import gated_solver
    from hmodel.surrogate.gate import fingerprint

    ens = get_solver("surrogate:ensemble")
    assert len(ens.members) == 3 and ens.model.meta["trust"]["kind"] == "ensemble"
    assert fingerprint(ens.members[0]) == fingerprint(load_shipped())  # the default network first
    assert ens.model.meta["trust"]["ranking"][1]["share_of_squared_error"] > 0.9  # measured when made
    gated = gated_solver("surrogate:ensemble", 0.5, "closed-form")
    spec = [s for s in standard_paths(0.01) if s.name == "drained"][0]
    ref, _ = run_path(PARAMS, spec, "closed-form", 2e-3, 1e-3)
    res, _ = run_path(PARAMS, spec, gated, 2e-3, 1e-3)
    assert gated.counts["gated"] > 0
    np.testing.assert_allclose(res.point(0)["q"], ref.point(0)["q"], rtol=2e-3, atol=1e-6 * ref.point(0)["q"].max())
