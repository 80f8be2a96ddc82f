"""The compliance formulation: exact contact law around learned compliances of eq. 1.7."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import CellState
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.data import DatasetSpec, compute_shard
from hmodel.surrogate import load, make_formulation, save
from hmodel.surrogate.formulations.compliance import MINUS, PLUS, STICK, _packed
from hmodel.surrogate.solver import SurrogateSolver
from hmodel.surrogate.training import TrainConfig, train


def exact_compliances(p: Params, values: np.ndarray) -> np.ndarray:
    """B and b of every regime from eq. 1.7's matrix as written in DESIGN.md step 2, inverted
    with numpy.linalg (independent of the compiled closed form), in the formulation's units."""
    d1, a, n1, t1 = values[:, 0], values[:, 2], values[:, 3], values[:, 5]
    ca, sa, gs = np.cos(a), np.sin(a), p.g2 + np.sin(a)
    out = np.empty((len(values), 24))
    two_r = 2 * p.radius
    for k, xi in ((STICK, 0.0), (PLUS, 1.0), (MINUS, -1.0)):
        A = np.zeros((len(values), 3, 3))
        A[:, 0] = np.column_stack([2 * ca, np.ones_like(a), -2 * d1 * sa])
        A[:, 1] = np.column_stack([2 * sa, np.zeros_like(a), 2 * d1 * ca])
        if xi == 0.0:
            A[:, 2] = np.column_stack([ca, -np.ones_like(a), (n1 * sa - t1 * ca - p.kt * d1 * gs) / p.kn])
        else:
            A[:, 2] = np.column_stack([ca + xi * p.tan_phi * gs, -np.ones_like(a), (n1 * sa - t1 * ca) / p.kn])
        inv = np.linalg.inv(A)  # [dd1, dd2, da] per unit [dl1, dl2, lam]
        scale = np.array([1 / two_r, 1 / two_r, 1.0])[:, None]  # outputs dd/2r, da per unit dl/2r
        B = inv * scale * two_r
        out[:, k:k + 6] = B[:, :, :2].reshape(len(values), 6)
        if xi != 0.0:
            out[:, k + 6:k + 9] = B[:, :, 2]
    return out


@pytest.fixture(scope="module")
def rows():
    spec = DatasetSpec(kind=2, n_directions=9, theta_min=-60, theta_max=150, alpha0_min=40,
                       alpha0_max=60, alpha0_step=10, max_strain=0.06, start_every=0.002,
                       magnitude=0.002, magnitude_min=0.0, n_increments=24, substeps=1)
    t = compute_shard(spec, Params(), 0)
    return {k: t.column(k).to_numpy() for k in t.column_names}


@pytest.mark.parametrize("rule", ["report", "equilibrium"])
def test_exact_compliances_reproduce_the_closed_form(rows, rule):
    # Every regime occurs: sticking, sliding both ways, openings, already-open cells.
    p = Params(sliding_rhs=rule)
    f = make_formulation("compliance", p)
    v = _packed(rows)
    assert rows["sliding"].any() and (rows["open1"] | rows["open2"]).any() and (v[:, 3] == 0).any()
    assert (rows["T1_next"][rows["sliding"]] < 0).any() and (rows["T1_next"][rows["sliding"]] > 0).any()
    dl = np.column_stack(f.length_increments(rows))
    new, flags = f.advance(v, dl, exact_compliances(p, v))
    ref, rflags = ClosedFormSolver().step(p, CellState(v), dl[:, 0], dl[:, 1])
    np.testing.assert_allclose(new, ref.values, rtol=1e-9, atol=1e-9 * p.kn)
    assert (flags == rflags.flags).mean() > 0.9999  # ties at the cone may flip in the last bit


def test_training_targets_are_met_by_the_exact_compliances(rows):
    # The loss of the exact compliances is zero (to rounding): the targets, the drive and the
    # regime selection of opened rows are consistent with eq. 1.7.
    p = Params()
    f = make_formulation("compliance", p)
    Y, W = f.targets(rows)
    pred = f.head(exact_compliances(p, _packed(rows)), f.aux(rows), Y)
    assert W.mean() > 0.99
    np.testing.assert_allclose(pred[W[:, 0] > 0], Y[W[:, 0] > 0], atol=1e-9)


def test_trained_compliance_model_round_trips_and_runs_in_the_rev(rows, tmp_path):
    from hmodel.compare import run_path, standard_paths

    s, hist = train(rows, Params(), TrainConfig(formulation="compliance", width=16, depth=2,
                                                activation="silu", epochs=30, seed=0))
    assert hist[-1]["val_loss"] < hist[0]["val_loss"]
    back = load(save(s, tmp_path / "c.safetensors"))
    assert back.formulation == s.formulation
    X = s.formulation.inputs(rows)
    np.testing.assert_array_equal(back.forward(X), s.forward(X))
    solver = SurrogateSolver(back)
    spec = next(x for x in standard_paths(0.01) if x.name == "oedometric")
    res, _ = run_path(Params(n_theta=12), spec, solver, 1e-3, 1e-4)
    assert np.all(np.isfinite(res["sig11"]))
    # One network evaluation per state and increment, at most: Newton's trials reuse it.
    assert 0 < solver.counts["network_cells"] <= 12 * len(res["sig11"])


def test_flagged_cells_take_the_closed_form_in_the_kernel(rows):
    """A response row whose flag is set (outside the training domain, or gated) is eq. 1.7's own
    increment in the compiled kernel; unflagged rows apply their compliances."""
    from hmodel.cell.closed_form import kernel_params
    from hmodel.cell.compliance_kernel import advance_cells, pack_responses

    p = Params()
    f = make_formulation("compliance", p)
    v = _packed(rows)
    dl = np.column_stack(f.length_increments(rows))
    wrong = exact_compliances(p, v) * 1.5  # compliances no cell would take
    flag = np.arange(len(v)) % 2 == 0
    out, flags = np.empty_like(v), np.empty((len(v), 5), dtype=np.bool_)
    assert advance_cells(v, dl, pack_responses(wrong, flag), kernel_params(p), out, flags) == -1
    ref, rflags = ClosedFormSolver().step(p, CellState(v[flag]), dl[flag, 0], dl[flag, 1])
    np.testing.assert_array_equal(out[flag], ref.values)
    np.testing.assert_array_equal(flags[flag], rflags.flags)
    learned, _ = f.advance(v[~flag], dl[~flag], wrong[~flag])
    np.testing.assert_array_equal(out[~flag], learned)


@pytest.mark.parametrize("name", ["drained", "undrained", "unload-reload"])
def test_compiled_compliance_rev_equals_the_generic_driver(name):
    """The shipped compliance network in the compiled loading path (its compliances evaluated
    once per increment, every Newton trial inside the kernel) against the generic driver, for
    two points at other pressures. Strain control: the same numbers. Mixed control: the same
    path to well within the trust bar (1 % of peak q): where cells break within an increment,
    the event state is a Newton trial, and the learned compliances' small jumps between regimes
    (``SurrogateSolver.stress_rtol``) let the two drivers' trials part at round-off."""
    from hmodel.loading import Recorder, Segment, consolidate, run_segment
    from hmodel.loading.compiled import supports
    from hmodel.rev import Rev
    from hmodel.surrogate.shipped import load_shipped

    solver = SurrogateSolver(load_shipped())
    rev = Rev(Params(n_theta=60), solver)
    assert supports(rev) and rev.kernel.learned
    s0 = consolidate(rev, [1e5, 3e5])
    if name == "undrained":
        segs = [Segment((False, False, False), np.array([[1.0, 0, 0], [1.0, 1.0, 0], [0, 0, 1.0]]),
                        np.array([0.02, 0.0, 0.0]), 40, "shear")]
    else:
        segs = [Segment.components("ESE", np.column_stack([[e] * 2, s0.sig[:, 1], [0.0] * 2]), n, "shear")
                for e, n in ((0.02, 40),) + (((-0.004, 8), (0.006, 12)) if name == "unload-reload" else ())]
    runs = []
    for compiled in (True, False):
        rec, s = Recorder(), s0
        for seg in segs:
            s = run_segment(rev, s, seg, recorder=rec, compiled=compiled).state
        runs.append((s, rec.result()))
    (sc, rc), (sg, rg) = runs
    q = lambda r: (r["sig11"] - r["sig22"]) / 2  # noqa: E731
    tol = 1e-12 if name == "undrained" else 1e-4
    np.testing.assert_allclose(q(rc), q(rg), rtol=0, atol=tol * np.abs(q(rg)).max())
    for col in ("eps22", "frac_sliding", "frac_open"):
        np.testing.assert_allclose(rc[col], rg[col], rtol=0, atol=tol)
    np.testing.assert_allclose(rc["sig22"], rg["sig22"], rtol=tol)
    assert solver.counts["outside"] == 0 and np.all(q(rc)[-1] > q(rc)[0])


def test_gated_solvers_take_the_generic_driver():
    """A gate (whose fallback may be another solver, an ensemble's decided per trial increment,
    its fraction recorded per increment) runs through the generic driver; without one, a single
    network or an ensemble has the compiled increment."""
    from hmodel.surrogate.shipped import load_shipped
    from hmodel.surrogate.solver import gated_solver

    p = Params()
    assert SurrogateSolver(load_shipped()).kernel(p) is not None
    assert gated_solver("surrogate:ensemble", None, None).kernel(p) is not None
    assert gated_solver("surrogate:ensemble", 0.99, "closed-form").kernel(p) is None
    assert gated_solver("surrogate", 0.99, "closed-form").kernel(p) is None
