"""The core install (``pip install hmodel``) has no PyTorch: inference is NumPy, and every
training path stops with one line that names the ``hmodel[train]`` extra."""

import subprocess
import sys
import textwrap

import pytest

from hmodel.errors import InputError
from hmodel.surrogate.torch_support import require_torch

# Run first in each subprocess: any import of torch (or of a torch submodule) fails as it does
# where PyTorch is not installed.
NO_TORCH = textwrap.dedent("""
    import importlib.abc, sys

    class _NoTorch(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "torch" or name.startswith("torch."):
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    sys.meta_path.insert(0, _NoTorch())
""")


def run_without_torch(code: str, tmp_path) -> subprocess.CompletedProcess:
    script = tmp_path / "script.py"
    script.write_text(NO_TORCH + textwrap.dedent(code))
    return subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=240)


def test_require_torch_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)  # ``import torch`` raises ImportError
    with pytest.raises(InputError, match=r"^distillation needs PyTorch: pip install 'hmodel\[train\]'$"):
        require_torch("distillation")


def test_inference_path_never_imports_torch(tmp_path):
    r = run_without_torch("""
        import sys
        import hmodel.cli.app, hmodel.surrogate.solver
        from hmodel.surrogate.shipped import load_shipped

        load_shipped()
        code = hmodel.cli.app.main(["run", "biaxial", "--p0", "200kPa", "--axial-strain", "0.002",
                                    "--solver", "surrogate", "--param", "n_theta=12", "--out", "o"])
        assert code == 0, code
        assert "torch" not in sys.modules
        assert "matplotlib.pyplot" not in sys.modules  # figures use no pyplot global state
        print("ok")
    """, tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().endswith("ok")
    assert (tmp_path / "o" / "result.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_training_without_torch_stops_with_one_line(tmp_path):
    r = run_without_torch("""
        import sys
        from hmodel.cli.app import main
        from hmodel.errors import InputError
        from hmodel.params import Params
        from hmodel.studies.reproduce import reproduce
        from hmodel.surrogate.distill import distill_on_sample
        from hmodel.surrogate.shipped import load_shipped
        from hmodel.surrogate.training import TrainConfig, train, train_on_sample

        for call in (lambda: train({}, Params(), TrainConfig()),
                     lambda: train_on_sample("no-such-sample", TrainConfig()),
                     lambda: distill_on_sample(load_shipped(), "no-such-sample"),
                     lambda: reproduce(__import__("pathlib").Path("full"), quick=False)):
            try:
                call()
            except InputError as e:
                assert "needs PyTorch: pip install 'hmodel[train]'" in str(e), e
            else:
                raise AssertionError("no InputError")
        for args in (["surrogate", "train", "no-such-sample", "--out", "m.safetensors"],
                     ["surrogate", "distill", "no-such-model.safetensors", "no-such-sample",
                      "--out", "m.safetensors"],
                     ["surrogate", "sweep", "no-such-dataset", "--out", "s"]):
            print(main(args))
        assert "torch" not in sys.modules
    """, tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["1", "1", "1"]
    assert r.stderr.splitlines() == [
        "hmodel: error: training needs PyTorch: pip install 'hmodel[train]'",
        "hmodel: error: distillation needs PyTorch: pip install 'hmodel[train]'",
        "hmodel: error: training needs PyTorch: pip install 'hmodel[train]'"]
    assert not (tmp_path / "full").exists() and not (tmp_path / "full.work").exists()
