"""Dataset kinds as classes (hmodel.data.kinds): found from the numbers manifests store, and a
new kind of rows is one class."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.data import Dataset, DatasetSpec, compute_shard, generate
from hmodel.data import kinds
from hmodel.data.kinds import KINDS, BiHexIncrements, Increments, dataset_kind
from hmodel.data.rows import increment_rows
from hmodel.data.schema import column_array
from hmodel.errors import InputError

SMALL = dict(n_directions=2, alpha0_min=40.0, alpha0_max=50.0, alpha0_step=10.0, max_strain=0.004,
             start_every=0.002, n_increments=4, substeps=2)


def test_every_kind_is_found_by_its_dataset_number_and_dimension():
    assert len({(k.number, k.dim) for k in KINDS}) == len(KINDS)
    for k in KINDS:
        assert dataset_kind(k.number, k.dim) is k
        spec = DatasetSpec(kind=k.number, dim=k.dim, rev_paths="drained:1e5" if k.number == 3 else "", **SMALL)
        assert spec.dataset_kind is k
    with pytest.raises(InputError, match=r"^dataset must be 1, 2 or 3, got 4$"):
        dataset_kind(4, 2)
    with pytest.raises(InputError, match=r"^dim must be 2 or 3, got 4$"):
        dataset_kind(2, 4)
    with pytest.raises(InputError, match="dataset 1 is the 2D H-cell's only"):
        dataset_kind(1, 3)


def test_a_dataset_opens_with_its_kind_from_the_manifest_numbers(tmp_path):
    for dim in (2, 3):
        spec = DatasetSpec(kind=2, dim=dim, **SMALL)
        generate(spec, Params(), tmp_path / f"d{dim}")
        ds = Dataset.open(tmp_path / f"d{dim}")
        assert ds.manifest["kind"] == 2 and ds.manifest["options"].get("dim", 2) == dim
        assert ds.spec.dataset_kind is spec.dataset_kind
        assert ds.manifest["columns"] == list(spec.dataset_kind.columns)
    assert isinstance(Dataset.open(tmp_path / "d3").spec.dataset_kind, BiHexIncrements)


class _FromRest(Increments):
    """A new kind: the increments from the unloaded cell of every path only."""

    number = 4

    def rows_per_path(self, spec):
        return spec.n_increments

    def path_rows(self, spec, params, solver, cells, dl1, dl2, paths, alpha0, theta, l0):
        return increment_rows(spec, params, solver, cells.values[:, None, :], l0, paths, alpha0, theta,
                              np.zeros(1))


def test_a_new_kind_of_rows_is_one_class(monkeypatch, tmp_path):
    monkeypatch.setattr(kinds, "KINDS", KINDS + (_FromRest(),))
    spec = DatasetSpec(kind=4, **SMALL)
    assert spec.n_rows == 2 * 2 * 4
    ds = generate(spec, Params(), tmp_path / "d4")
    assert ds.manifest["kind"] == 4 and ds.n_rows == spec.n_rows
    rows = ds.read()
    # they are the rows of dataset 2 from the unloaded cell
    t = compute_shard(DatasetSpec(kind=2, from_unloaded=True, **SMALL), Params(), 0)
    d2 = {c: column_array(t, c) for c in t.column_names}
    at_rest = d2["start_strain"] == 0.0
    for c in rows:
        assert np.array_equal(rows[c], d2[c][at_rest]), c
