"""Markers and fixtures shared by the test modules.

- ``@pytest.mark.yade``: the test drives the YADE executable; skipped, with the reason, where
  YADE is not installed (``.ci/run`` installs it, so CI runs every one).
- ``@pytest.mark.slow``: one of the slowest tests (4 s or more on the project's 2-core machine).
  CI still runs it; ``python -m pytest -m "not slow"`` leaves it out while editing.

A test that checks a contract the 2D and the 3D model share takes the ``dim`` fixture (2, then
3) or a ``pytest.mark.parametrize`` over ``dim`` where its cases differ by dimension; the
physics of one dimension stays in that dimension's module (``test_rev3d.py``, ...).
"""

import math
from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np
import pytest

from hmodel import Params
from hmodel.cli.app import main
from hmodel.data import DatasetSpec, generate
from hmodel.data.sampling import write_split
from hmodel.dem.yade import available
from hmodel.surrogate.modelfile import load, save
from hmodel.surrogate.training import TrainConfig, train_on_sample


def pytest_collection_modifyitems(config, items):
    if available():
        return
    skip = pytest.mark.skip(reason="YADE is not installed (apt-get install -y yade)")
    for item in items:
        if "yade" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(params=[2, 3], ids=["2d", "3d"])
def dim(request):
    """The model's dimension: a test taking it runs for the 2D model, then for the 3D one."""
    return request.param


class Cli:
    """``hmodel`` run in this process, its output captured."""

    def __init__(self, capsys):
        self._capsys = capsys

    def __call__(self, *args) -> tuple[int, str, str]:
        """Run ``hmodel args``: the exit status, stdout and stderr."""
        code = main([str(a) for a in args])
        out, err = self._capsys.readouterr()
        return code, out, err

    def refuses(self, args, word: str, out, code: int = 1) -> str:
        """Run ``hmodel args`` and check the error contract (docs/cli.md): exit status ``code``,
        one line ``hmodel: error: ...`` naming ``word``, and ``out`` not written. Its stderr."""
        got, _, err = self(*args)
        assert got == code and err.count("\n") == 1 and err.startswith("hmodel: error: "), err
        assert word in err, err
        assert not out.exists()
        return err


@pytest.fixture
def cli(capsys):
    """``cli(*args)`` runs ``hmodel args`` in process: (exit status, stdout, stderr);
    ``cli.refuses(args, word, out)`` checks that it is refused in one line naming ``word``."""
    return Cli(capsys)


#: Dataset 2 of the closed form, small: 7 directions at alpha0 40, 45 and 50 degrees (2,520 rows)
SMALL_SPEC = DatasetSpec(kind=2, n_directions=7, theta_min=-60, theta_max=150, alpha0_min=40, alpha0_max=50,
                         alpha0_step=5, max_strain=0.04, step=0.001, start_every=0.004, magnitude=0.002,
                         magnitude_min=0.0, n_increments=12, substeps=1)


@pytest.fixture(scope="session")
def small_sample(tmp_path_factory):
    """The folder of a training sample (2,000 rows, 400 held out, drawn at random with seed 0)
    of :data:`SMALL_SPEC` at the default parameters, made once for the session; read-only."""
    root = tmp_path_factory.mktemp("small")
    write_split(generate(SMALL_SPEC, Params(), root / "d"), root / "sample", 2000, 400, "random", 0)
    return root / "sample"


@pytest.fixture(scope="session")
def tiny_model(tmp_path_factory):
    """A small meso network of the closed-form H-cell, trained once for the session on a
    Dataset 2 sample (also returned: the folder of its data and sample)."""
    tmp = tmp_path_factory.mktemp("meso")
    spec = DatasetSpec(kind=2, n_directions=8, theta_min=-60.0, theta_max=150.0, alpha0_min=45.0,
                       alpha0_max=45.0, max_strain=0.02, step=0.001, start_every=0.002,
                       magnitude=0.002, magnitude_min=0.0, n_increments=12, substeps=1)
    ds = generate(spec, Params(sliding_rhs="equilibrium"), tmp / "data")
    write_split(ds, tmp / "sample", 700, 150)
    cfg = TrainConfig(formulation="meso", width=32, depth=2, activation="silu", epochs=80,
                      patience=80, device="cpu")
    model, _ = train_on_sample(tmp / "sample", cfg)
    return load(save(model, tmp / "meso.safetensors")), tmp


@dataclass(frozen=True)
class OwnTests:
    """Calibration data made by hmodel itself at known parameters (:attr:`true`): the 2D
    model's biaxial tests (36 directions) or the 3D model's triaxial tests (Lebedev order 9, two
    azimuths, the command line's axis), with ``sliding_rhs="equilibrium"`` as the 3D commands
    default it (the report's λ stops the 3D Newton near 1 %)."""

    dim: int

    @property
    def base(self) -> Params:
        return Params(n_theta=36, sliding_rhs="equilibrium") if self.dim == 2 else Params(sliding_rhs="equilibrium")

    @property
    def true(self) -> Params:
        return self.base.with_(phi_g=math.radians(28.0), alpha0=math.radians(50.0), kt_kn=0.5)

    @property
    def kw(self) -> dict:
        """The increments (and in 3D the rule) the tests are made and fitted with."""
        from hmodel.rev import Sphere

        kw = {"step": 1e-3, "iso_step": 1e-4}
        return kw if self.dim == 2 else {**kw, "sphere": Sphere(order=9, n_azimuth=2, axis=(1.0, 0.0, 0.0))}

    def test(self, kind, p0, strain=0.02, noise=0.0, noise_ev=0.0, seed=0):
        """The test ``kind`` at :attr:`true` by the kind's own run: every second shear row, q
        with relative Gaussian noise, εv with absolute Gaussian noise (none where undrained);
        compression positive (extension: eps11 < 0)."""
        from hmodel.calibrate import Kind, Test

        kind = Kind(kind)
        r = kind.run([self.true], [p0], strain, solver=None, sphere=self.kw.get("sphere"), step=1e-3,
                     iso_step=1e-4)
        c, s = r.stage("consolidation"), r.stage("shear")
        e = np.asarray(s["eps11"]) - c["eps11"][-1]
        rng = np.random.default_rng(seed)
        q = np.asarray(s["q"]) * (1 + noise * rng.normal(size=len(e)))
        ev = np.asarray(s["eps_v"]) - c["eps_v"][-1] + noise_ev * rng.normal(size=len(e))
        sel = slice(1, None, 2)
        return Test(kind, p0, e[sel], q[sel], None if kind.undrained else ev[sel])

    @cached_property
    def tests(self) -> tuple:
        """The noise-free tests the calibration modules share: drained at 100 and 300 kPa (and
        in 3D undrained and extension at 200 kPa)."""
        kinds = [("drained", 1e5), ("drained", 3e5)] if self.dim == 2 else [
            ("triaxial-drained", 1e5), ("triaxial-drained", 3e5), ("triaxial-undrained", 2e5),
            ("triaxial-extension", 2e5)]
        return tuple(self.test(k, p0) for k, p0 in kinds)


@pytest.fixture(scope="session")
def own_tests():
    """``own_tests(dim)``: the :class:`OwnTests` of that dimension, one per session (its
    noise-free tests are made once)."""
    return cache(OwnTests)


def _check_cell_jacobian(state, dl, regime: str, p, two_r: float, vsigma, scale: float, atol: float):
    """The exact tangent of a cell (closed_form.cell_jacobian) against central differences of its
    update, in the regime the case names: ``dl`` None takes the first of a few increments of
    size ``scale`` that pushes T1 past the cone in the direction of ``regime`` ("sliding +",
    "sliding -"); ``vsigma(r)`` is (V σnn, V σtt) of an update's result ``r``."""
    from hmodel.cell.closed_form import cell_jacobian, cell_update

    if dl is None:
        sign = 1.0 if regime.endswith("+") else -1.0
        dl = next(x for x in scale * np.array([(-4, 1), (4, -1), (1, 4), (-1, -4)])
                  if cell_update(*state, *x, p)[9] and np.sign(cell_update(*state, *x, p)[6]) == sign)
    dl = np.asarray(dl, float)
    r0 = cell_update(*state, *dl, p)
    # the update took the regime the case names (else the case tests something else)
    assert r0[0]
    assert r0[9] == regime.startswith("sliding")
    assert (r0[10] or r0[11]) == (regime == "open")
    assert (r0[7] <= two_r) == (regime == "over-compressed")
    ok, *jac = cell_jacobian(*state, *dl, p)
    assert ok
    J = np.array(jac).reshape(2, 2)  # rows (V σnn, V σtt), columns (dl1, dl2)
    h = 1e-4 * np.abs(dl).max()  # far below the distance to the regime's kinks
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        plus = cell_update(*state, *(dl + e), p)
        minus = cell_update(*state, *(dl - e), p)
        assert plus[9:] == r0[9:] and minus[9:] == r0[9:]  # the same regime either side
        slope = (vsigma(plus) - vsigma(minus)) / (2 * h)
        np.testing.assert_allclose(J[:, k], slope, rtol=1e-6, atol=atol * np.abs(J).max())
    if regime == "open":
        assert np.all(J == 0)  # no contact force, no extra contact (l1, l2 > 2r)
    else:
        assert np.abs(J).max() > 0


@pytest.fixture
def jacobian_check():
    """:func:`_check_cell_jacobian`: a cell's exact tangent against central differences."""
    return _check_cell_jacobian
