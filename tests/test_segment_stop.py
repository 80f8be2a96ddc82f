"""Per-point stop criteria of the one segment runner: each material point ends on its own."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.loading.segment import MeanStressReaches
from hmodel.rev import Rev

SMALL = Params(n_theta=36)
P0 = [1e5, 2e5, 3e5]
#: q at which each point of the batch ends (a different increment for each)
Q_END = np.array([1.8e5, 3.5e5, 5.9e5])
DRAINED = Segment.components("ESE", [0.03, 0.0, 0.0], 150, "shear")


def _drained(p0):
    """The drained segment at lateral stresses ``p0`` (B,)."""
    values = np.zeros((len(p0), 3))
    values[:, 0], values[:, 1] = 0.03, p0
    return Segment(DRAINED.stress_rows, DRAINED.matrix, values, 150, "shear")


def _q_reaches(targets):
    targets = np.asarray(targets)
    return lambda cols: cols["q"] >= np.tile(targets, len(cols["q"]) // len(targets))


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("before", [False, True])
def test_each_point_stops_on_its_own_as_it_would_alone(compiled, before):
    rev = Rev(SMALL)
    s0 = consolidate(rev, P0)
    rec = Recorder()
    out = run_segment(rev, s0, _drained(P0), rec, stop=_q_reaches(Q_END), stop_before=before,
                      compiled=compiled)
    res = rec.result()
    assert out.stopped.all() and out.increments < 150
    counts = [len(res.point(b)) for b in range(len(P0))]
    assert len(set(counts)) == len(P0)  # they did end at different increments
    for b in range(len(P0)):
        q = res.point(b)["q"]
        if before:  # the state that meets it is not kept
            assert q[-1] < Q_END[b] and out.met["q"][b] == q[-1]
        else:
            assert q[-1] >= Q_END[b] > q[-2] and out.met["q"][b] == q[-1]
        one = consolidate(Rev(SMALL), [P0[b]])
        alone = run_segment(Rev(SMALL), one, _drained([P0[b]]), stop=_q_reaches([Q_END[b]]),
                            stop_before=before, compiled=compiled)
        np.testing.assert_array_equal(out.state.sig[b], alone.state.sig[0])
        np.testing.assert_array_equal(out.state.cells.values[b], alone.state.cells.values[0])


@pytest.mark.parametrize("before", [False, True])
def test_the_kernels_mean_stress_criterion_equals_the_same_criterion_in_python(before):
    # in the kernel, increment by increment; in Python, on each chunk's records with the points
    # that met it run again up to there: the same states
    rev = Rev(SMALL)
    s0 = rev.initial(3)
    seg = Segment((False,) * 3, np.eye(3), np.array([1e-5, 1e-5, 0.0]), 10_000, "consolidation",
                  per_increment=True)
    target = np.array([0.5e5, 1e5, 2e5])
    outs = []
    for stop in (MeanStressReaches(target), lambda cols: MeanStressReaches(target)(cols)):
        rec = Recorder()
        outs.append((run_segment(rev, s0, seg, rec, stop=stop, stop_before=before), rec.result()))
    (a, ra), (b, rb) = outs
    assert a.stopped.all() and a.increments == b.increments < 10_000
    np.testing.assert_array_equal(a.state.sig, b.state.sig)
    np.testing.assert_array_equal(a.state.cells.values, b.state.cells.values)
    np.testing.assert_array_equal(ra["step"], rb["step"])
    np.testing.assert_array_equal(ra["p"], rb["p"])
    assert (a.state.p < target).all() if before else (a.state.p >= target).all()


def test_consolidation_runs_no_increment_twice(monkeypatch):
    """The compression of a consolidation ends in the kernel (its criterion is the kernel's):
    one kernel call for its increments, one for the last increment to p0."""
    import hmodel.loading.compiled as compiled

    calls = []
    real = compiled._run_steps

    def counted(*args):
        calls.append(int(args[12]) - int(args[11].min()))  # increments asked for
        return real(*args)

    monkeypatch.setattr(compiled, "_run_steps", counted)
    rec = Recorder()
    s = consolidate(Rev(SMALL), [2e5], recorder=rec)
    assert calls == [100, 1] and len(rec.result()) < 100 and s.p[0] == pytest.approx(2e5, rel=1e-12)


def test_a_segment_of_per_increment_values_takes_strain_rows_only():
    with pytest.raises(Exception, match="strain rows"):
        Segment((False, True, False), np.eye(3), np.zeros(3), 10, "x", per_increment=True)
