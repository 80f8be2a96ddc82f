"""A model's metrics on data folders from Python (hmodel.surrogate.folder_evaluation), as
``hmodel surrogate evaluate`` reports them."""

from hmodel import Params
from hmodel.data import DatasetSpec, generate
from hmodel.surrogate import modelfile
from hmodel.surrogate.folder_evaluation import evaluate_folder
from hmodel.surrogate.shipped import model_path

SMALL = dict(kind=2, n_directions=2, alpha0_min=40.0, alpha0_max=50.0, alpha0_step=10.0, max_strain=0.004,
             start_every=0.002, n_increments=4, substeps=1, magnitude=0.002)


def test_2d_rows_get_a_parity_plot_and_bihexagon_rows_the_learned_3d_cell(tmp_path):
    s = modelfile.load(model_path("shipped"))
    for dim in (2, 3):
        generate(DatasetSpec(dim=dim, **SMALL), Params(), tmp_path / f"d{dim}")
    rows, parity = evaluate_folder(s, tmp_path / "d2", rows=10, seed=1)
    assert {r["data"] for r in rows} == {"d2 (dataset 2)"} and len({r["output"] for r in rows}) >= 8
    parity(tmp_path / "p.png", "m")
    assert (tmp_path / "p.png").stat().st_size > 0
    rows, parity = evaluate_folder(s, tmp_path / "d3", rows=10, seed=1)
    assert parity is None and {r["data"] for r in rows} == {"d3 (3D dataset 2)"}
    assert {r["quantity"] for r in rows} == {"state after", "increment", "meso-stress"}
