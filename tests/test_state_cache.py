"""The surrogate's cache of network outputs: lookups by the states' values, its memory bounds,
and a REV of many parameter sets costing no more inference than each set run alone."""

from __future__ import annotations

import pickle

import numpy as np

from hmodel import Params
from hmodel.loading import run_biaxial
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver
from hmodel.surrogate.state_cache import MIN_ENTRIES, StateCache


def test_lookup_is_by_value():
    c = StateCache()
    v = np.arange(12.0).reshape(4, 3)
    c.put(v, "a")
    assert c.get(v.copy()) == "a"
    w = v.copy()
    w[2, 1] += 1e-12
    assert c.get(w) is None
    assert c.get(v.reshape(3, 4)) is None  # same bytes, other shape
    v[0, 0] = -1.0  # the cache kept its own copy
    assert c.get(v) is None and c.get(np.arange(12.0).reshape(4, 3)) == "a"


def test_batches_that_differ_outside_the_hashed_rows_are_told_apart():
    """The key hashes a sample of a large batch's rows; two batches that differ elsewhere share
    a key but never each other's values."""
    from hmodel.surrogate.state_cache import KEY_ROWS
    c = StateCache()
    v = np.arange(8.0 * 4 * KEY_ROWS).reshape(-1, 8)
    w = v.copy()
    w[1] += 0.5  # a row between the sampled ones
    assert c._key(v) == c._key(w)
    c.put(v, "v")
    assert c.get(w) is None and c.get(v.copy()) == "v"
    c.put(w, "w")
    assert c.get(w.copy()) == "w" and c.get(v) is None  # the newer batch replaced the older


def test_distinct_rows_are_exact():
    """Equal rows share one representative, wherever they are; rows that differ in their last
    bit (whose weighted sums may round alike) never do; a batch whose sampled rows all differ
    is left as it is."""
    from hmodel.surrogate.state_cache import distinct_rows
    rng = np.random.default_rng(1)
    base = rng.normal(size=(5, 8))
    v = base[rng.integers(0, 5, 400)]
    v[::7, 3] = np.nextafter(v[::7, 3], np.inf)  # one ulp off
    first, inverse = distinct_rows(v)
    np.testing.assert_array_equal(v[first][inverse], v)
    assert len(first) < 50 and len(np.unique(v[first], axis=0)) >= len(np.unique(v, axis=0))
    assert distinct_rows(rng.normal(size=(30, 8))) is None and distinct_rows(v[:1]) is None


def test_bounds_drop_the_least_recently_used():
    c = StateCache(max_entries=3)
    vs = [np.full((2, 2), float(k)) for k in range(4)]
    for k in range(3):
        c.put(vs[k], k)
    assert c.get(vs[0]) == 0  # now the most recent
    c.put(vs[3], 3)
    assert len(c) == 3 and c.get(vs[1]) is None and c.get(vs[0]) == 0
    small = StateCache(max_bytes=100)
    for k in range(4):
        small.put(np.full((10, 10), float(k)), np.zeros(10))  # 880 bytes each
    assert len(small) == MIN_ENTRIES  # the last ones are kept whatever their size
    assert small.get(np.full((10, 10), 3.0)) is not None and small.get(np.full((10, 10), 0.0)) is None


def test_many_parameter_sets_cost_the_inference_of_each_alone():
    """Eight opening angles in one REV: the network sees each set's cell states once per
    increment, as in eight separate runs (a cache of the last batch alone made the batched run
    evaluate every set again at every Newton trial)."""
    sets = [Params(n_theta=36, alpha0=np.radians(a)) for a in range(40, 80, 5)]
    batched = SurrogateSolver(load_shipped())
    together = run_biaxial(sets, [2e5] * len(sets), 0.01, solver=batched, step=1e-3, iso_step=1e-4)
    alone = 0
    for b, p in enumerate(sets):
        s = SurrogateSolver(load_shipped())
        one = run_biaxial(p, [2e5], 0.01, solver=s, step=1e-3, iso_step=1e-4)
        alone += s.counts["network_cells"]
        np.testing.assert_allclose(together.point(b)["q"], one["q"], rtol=1e-9, atol=1e-6)
    assert batched.counts["network_cells"] == alone


def test_a_pickled_solver_starts_with_an_empty_cache():
    s = SurrogateSolver(load_shipped())
    run_biaxial(Params(n_theta=12), [1e5], 0.002, solver=s, step=1e-3, iso_step=1e-4)
    assert len(s._cache) > 0
    assert len(pickle.loads(pickle.dumps(s))._cache) == 0
