"""DEM data -> surrogate -> ANN-based REV next to the DEM-REV (benchmarks/dem/dem_ann.py, tiny sizes)."""

from __future__ import annotations

import numpy as np
import pytest

from hmodel.data import DatasetSpec, generate
from hmodel.data.sampling import write_split
from hmodel.loading import run_biaxial
from hmodel.params import Params
from hmodel.solvers import get_solver
from hmodel.surrogate.distill import DistillConfig, _TeacherRollouts, distill
from hmodel.surrogate.modelfile import load, save
from hmodel.surrogate.solver import SurrogateSolver
from hmodel.surrogate.training import TrainConfig, torch_network, train_on_sample
from hmodel.surrogate.training_rows import read_sample

PARAMS = Params(sliding_rhs="equilibrium", n_theta=6)


def _side_by_side(ann: SurrogateSolver, dem: str, rtol: float = 0.1) -> None:
    """The ANN-REV and the DEM-REV run the same short drained path, both hold the lateral
    stress, and their consolidation strains agree within ``rtol``."""
    kw = dict(axial_strain=0.002, step=1e-3, iso_step=2e-4)
    res_ann = run_biaxial(PARAMS, [2e5], solver=ann, **kw)
    res_dem = run_biaxial(PARAMS, [2e5], solver=get_solver(dem), **kw)
    assert len(res_ann.stage("shear")) == len(res_dem.stage("shear"))
    for res in (res_ann, res_dem):
        assert np.all(np.isfinite(np.asarray(res["q"])))
        assert abs(np.asarray(res["sig22"])[-1] - 2e5) <= 1e-5 * 2e5
    iso_ann = np.asarray(res_ann.stage("consolidation")["eps_v"])[-1]
    iso_dem = np.asarray(res_dem.stage("consolidation")["eps_v"])[-1]
    assert abs(iso_ann - iso_dem) <= rtol * abs(iso_dem)


@pytest.mark.yade
def test_surrogate_trained_on_dem_rows_runs_in_the_rev_next_to_the_dem(tmp_path):
    """Single DEM increments (REV_DATASET recipe, tiny) train the compliance formulation; the
    model file records its DEM provenance and the material; the ANN-REV and the DEM-REV run
    the same drained biaxial path row for row, both keep the lateral stress at p0 and start
    from the same isotropic state (elastic sticking cells: the learned compliances reproduce
    the DEM's consolidation strain within 10 % after
    600 epochs on 100 rows)."""
    spec = DatasetSpec(kind=2, n_directions=3, theta_min=-60.0, theta_max=150.0, alpha0_min=45.0,
                       alpha0_max=45.0, max_strain=0.004, step=0.001, start_every=0.002,
                       magnitude=0.002, magnitude_min=0.0, n_increments=24, substeps=1,
                       solver="dem:standard")
    ds = generate(spec, PARAMS, tmp_path / "data")
    assert ds.n_rows == 3 * 2 * 24
    write_split(ds, tmp_path / "sample", 100, 30)
    cfg = TrainConfig(formulation="compliance", width=32, depth=2, activation="silu", epochs=600,
                      patience=600, device="cpu")
    model, _ = train_on_sample(tmp_path / "sample", cfg)
    path = save(model, tmp_path / "m.safetensors")
    loaded = load(path)
    assert "dem:standard" in str(loaded.meta["training_data"])
    assert loaded.meta["params"]["sliding_rhs"] == "equilibrium"

    ann = SurrogateSolver(loaded, on_outside="fallback")
    _side_by_side(ann, "dem:standard")
    assert ann.counts["network_cells"] > 0


@pytest.mark.yade
def test_meso_surrogate_of_the_hexagon_center_cell_runs_next_to_its_dem_rev(tmp_path):
    """The richer cell: DEM rows with their extra state -> sample -> meso formulation -> the
    ANN-REV (summary states, Love-Weber stress from the model) beside the DEM-REV on a short
    drained path; both hold the lateral stress, and the consolidation strains agree within 25 %
    after 300 epochs on 180 rows (the pipeline, not the accuracy: see benchmarks/dem/dem_ann.py)."""
    solver = "dem:hexagon-center:tol=1e-7,max_iter=100000"
    spec = DatasetSpec(kind=2, n_directions=3, theta_min=-60.0, theta_max=150.0, alpha0_min=45.0,
                       alpha0_max=45.0, max_strain=0.004, step=0.001, start_every=0.002,
                       magnitude=0.002, magnitude_min=0.0, n_increments=24, substeps=1,
                       solver=solver, from_unloaded=True)
    ds = generate(spec, PARAMS, tmp_path / "data")
    assert ds.n_rows == 3 * 3 * 24 and ds.n_extra == 35
    write_split(ds, tmp_path / "sample", 180, 30)
    cfg = TrainConfig(formulation="meso", width=32, depth=2, activation="silu", epochs=300,
                      patience=300, device="cpu")
    model, _ = train_on_sample(tmp_path / "sample", cfg)
    loaded = load(save(model, tmp_path / "m.safetensors"))
    assert loaded.formulation.name == "meso" and loaded.formulation.cell == solver
    _side_by_side(SurrogateSolver(loaded, on_outside="fallback"), solver, rtol=0.25)

    # distilled: a student follows the teacher's rollouts along the data's paths, whose targets
    # are the teacher's own (the teacher itself is off them by float32 round-off only)
    cols, _ = read_sample(tmp_path / "sample", "train")
    cfg = DistillConfig(width=8, depth=2, epochs=3, rollout=2)
    assert _TeacherRollouts(loaded, cols, cfg, np.random.default_rng(0), torch_network(loaded)).validation() < 1e-12
    student, history = distill(loaded, cols, cfg)
    assert student.architecture.width == 8 and np.isfinite(history[-1]["val_loss"])
