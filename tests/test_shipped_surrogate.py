"""The shipped surrogate and the surrogate cell solver (the cell-solver interface)."""

import numpy as np
import pytest

from hmodel import InputError, Params, SolverError
from hmodel.cell import CellState
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.data import DatasetSpec, compute_shard
from hmodel.surrogate.formulations import OUTPUTS
from hmodel.surrogate.metrics import regression_metrics
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver, load_solver


@pytest.fixture(scope="module")
def shipped():
    """The report-style surrogate (formulation ``increment``, 1 % increments)."""
    return load_shipped("increment")


@pytest.fixture(scope="module")
def default():
    """The default surrogate of the ANN-based H-model (formulation ``compliance``)."""
    return load_shipped()


@pytest.mark.parametrize("name, formulation", [("increment", "increment"), ("default", "compliance")])
def test_shipped_models_load_with_their_provenance(name, formulation):
    m = load_shipped(name).meta
    assert m["formulation"]["name"] == formulation and m["training_data"]["source_checksum"]
    r2 = {r["output"]: r["r2"] for r in m["metrics"] if r["quantity"] == "state after"}
    assert min(r2.values()) > 0.999


def _fresh_rows(**options):
    # Rows no model saw: Dataset-2 increments from other alpha0 and directions than the grids'.
    spec = DatasetSpec(kind=2, n_directions=4, alpha0_min=41, alpha0_max=71, alpha0_step=15, **options)
    t = compute_shard(spec, Params(), 0)
    c = {k: t.column(k).to_numpy() for k in t.column_names}
    keep = ~(c["open1"] | c["open2"]) & (c["l1_next"] >= 2) & (c["l2_next"] >= 2)
    return {k: v[keep] for k, v in c.items()}


def _r2(model, c):
    pred = model.predict(c)
    return regression_metrics(np.column_stack([c[k] for k in OUTPUTS]),
                              np.column_stack([pred[k] for k in OUTPUTS]))["r2"]


def test_shipped_model_predicts_fresh_closed_form_rows(shipped):
    r2 = _r2(shipped, _fresh_rows(max_strain=0.25, start_every=0.05, n_increments=30))
    assert np.all(r2 > 0.999), r2


def test_default_model_predicts_fresh_rev_scale_increments(default):
    c = _fresh_rows(theta_min=-50, theta_max=140, max_strain=0.15, start_every=0.005,
                    magnitude=0.002, magnitude_min=0.0, n_increments=30, substeps=1)
    before = np.column_stack([c[k] for k in ("alpha", "N1", "N2", "T1")])
    pred = default.predict(c)
    inc = regression_metrics(np.column_stack([c[k] for k in OUTPUTS]) - before,
                             np.column_stack([pred[k] for k in OUTPUTS]) - before)["r2"]
    assert np.all(inc > 0.999), inc  # R² of the increments themselves, not of the states


def _cells(n=50):
    p = Params()
    rng = np.random.default_rng(0)
    state = CellState.initial(p, (n,))
    solver = ClosedFormSolver()
    for _ in range(20):
        state, _ = solver.step(p, state, -p.l10 * 1e-3 * rng.uniform(0.2, 1, n), -p.l20 * 1e-3 * rng.uniform(0.2, 1, n))
    return p, state


def test_solver_keeps_geometry_consistent_and_coulomb(shipped):
    p, state = _cells()
    s = SurrogateSolver(shipped)
    new, flags = s.step(p, state, -p.l10 * 0.005, -p.l20 * 0.002)
    np.testing.assert_allclose(new.geometric_l1(), new.l1, rtol=1e-12)
    np.testing.assert_allclose(new.geometric_l2(), new.l2, rtol=1e-12)
    assert np.all(np.abs(new.T1) <= p.tan_phi * new.N1 * (1 + 1e-12))
    np.testing.assert_allclose(new.l1, state.l1 - p.l10 * 0.005)


def test_large_increments_are_split(shipped):
    p, state = _cells()
    s = SurrogateSolver(shipped)
    s.step(p, state, -p.l10 * 0.035, 0.0)
    assert s.counts["substeps"] == 4  # 3.5 % in steps of at most the trained 1 %


@pytest.mark.parametrize("name", ["default", "increment"])
@pytest.mark.parametrize("mode", ["fallback", "error"])
def test_out_of_domain_cells_are_detected(name, mode):
    p, state = _cells(4)
    v = state.values.copy()
    v[0, 3] *= 50  # N1 fifty times larger than anything trained
    far = CellState(v)
    s = SurrogateSolver(load_shipped(name), on_outside=mode)
    if mode == "error":
        with pytest.raises(SolverError, match="outside the surrogate's training domain"):
            s.step(p, far, -p.l10 * 1e-3, 0.0)
    else:
        new, _ = s.step(p, far, -p.l10 * 1e-3, 0.0)
        ref, _ = ClosedFormSolver().step(p, CellState(v[:1]), -p.l10 * 1e-3, 0.0)
        np.testing.assert_array_equal(new.values[0], ref.values[0])
        assert s.counts["outside"] == 1


def test_solver_refuses_another_material(shipped):
    p, state = _cells(3)
    with pytest.raises(InputError, match="kn"):
        SurrogateSolver(shipped).step(p.with_(kn=1e8), state, 0.0, 0.0)
    from hmodel.solvers import get_solver
    from hmodel.surrogate import ModelFileError
    with pytest.raises(InputError, match="solver"):
        get_solver("neural")
    with pytest.raises(ModelFileError, match="does not exist"):
        load_solver("surrogate:/nonexistent.safetensors")
