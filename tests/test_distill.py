"""Distilling a meso surrogate into a narrower network (hmodel.surrogate.distill)."""

from __future__ import annotations

import numpy as np
import pytest
from hmodel.errors import InputError
from hmodel.surrogate.distill import DistillConfig, distill, distill_on_sample
from hmodel.surrogate.modelfile import load
from hmodel.surrogate.shipped import model_path
from hmodel.surrogate.training_rows import read_sample


def _increment_gap(student, teacher, cols, seed=1):
    """RMS of the students' increments dz/m0 minus the teacher's on the rows' states, each with
    a random strain of the data's size."""
    f = teacher.formulation
    X = f.inputs(cols)
    e = f.aux(cols)
    e = np.random.default_rng(seed).permutation(e)  # strains of the data's size, other states
    d = f.head(student.forward(X), e) - f.head(teacher.forward(X), e)
    return float(np.sqrt(np.mean(d * d)))


def test_a_student_learns_its_teachers_increments(tiny_model):
    teacher, tmp = tiny_model
    cols, _ = read_sample(tmp / "sample", "train")
    test, _ = read_sample(tmp / "sample", "test")
    cfg = DistillConfig(width=16, depth=2, epochs=1, seed=0)
    untrained, _ = distill(teacher, cols, cfg)
    student, history = distill_on_sample(teacher, tmp / "sample", DistillConfig(width=16, depth=2, epochs=60))
    # it keeps the teacher's formulation, scalers and training domain, and says whose it is
    assert student.formulation.to_dict() == teacher.formulation.to_dict()
    np.testing.assert_array_equal(student.input_range, teacher.input_range)
    np.testing.assert_array_equal(student.x_scaler.offset, teacher.x_scaler.offset)
    assert student.architecture.width == 16 and student.architecture.activation == teacher.architecture.activation
    assert student.meta["distilled"]["config"]["width"] == 16 and student.meta["metrics"]
    # training lowered the loss and brought the increments to the teacher's (on held-out rows)
    assert history[-1]["val_loss"] < history[0]["val_loss"]
    gap0, gap = _increment_gap(untrained, teacher, test), _increment_gap(student, teacher, test)
    assert gap < 0.3 * gap0


def test_only_meso_teachers_and_sound_settings():
    with pytest.raises(InputError, match="meso"):
        distill(load(model_path("shipped")), {}, DistillConfig())
    with pytest.raises(InputError, match="width"):
        DistillConfig(width=0)
    with pytest.raises(InputError, match="raw_weight"):
        DistillConfig(raw_weight=-1.0)


def test_cli_distill_writes_a_student(tiny_model, tmp_path, cli):
    teacher, tmp = tiny_model
    out = tmp_path / "student.safetensors"
    args = ["surrogate", "distill", str(tmp / "meso.safetensors"), str(tmp / "sample"), "--width", "8",
            "--depth", "2", "--epochs", "3", "--out"]
    code, stdout, _ = cli(*args, out)
    assert code == 0 and "student" in stdout
    assert load(out).architecture.width == 8
    code, _, err = cli(*args, tmp_path / "x.pt")
    assert code == 1 and "safetensors" in err and err.count("\n") == 1 and not (tmp_path / "x.pt").exists()
