"""The REV's kernel interface: both REVs give their compiled trial's inputs in one encoding,
and one trial function runs a point of either."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.errors import InputError
from hmodel.loading.compiled import cell_responses_of, kernel_inputs
from hmodel.rev import Rev, Rev3D, Sphere
from hmodel.rev.trial import point_trial

SETS = [Params(n_theta=36), Params(n_theta=36, phi_g=np.radians(20), alpha_omega=0.3)]


def _revs():
    return [Rev(SETS), Rev3D([Params(), Params(phi_g=np.radians(20))], Sphere(order=7, n_azimuth=2))]


@pytest.mark.parametrize("rev", _revs(), ids=["2d", "3d"])
def test_one_encoding_one_trial_for_both_revs(rev):
    geo, p = rev.kernel_inputs()
    # a block of rows (cells, width) per parameter set, or one for all; packed parameters per set
    assert geo.ndim == 3 and geo.shape[0] in (1, rev.n_sets) and geo.shape[1] == rev.n_cells
    assert p.shape[0] == rev.n_sets and geo.flags.c_contiguous and p.flags.c_contiguous
    assert rev.kernel_inputs()[0] is geo  # built once
    s = rev.initial(rev.n_sets)
    deps = np.zeros((rev.n_sets, rev.n_components))
    deps[:, 0], deps[:, 1] = 2e-4, 1e-4
    ref = rev.step(s, deps)
    for k in range(rev.n_sets):
        g, pk = kernel_inputs(rev, k)
        values = np.ascontiguousarray(s.cells.values[k])
        out, flags = np.empty_like(values), np.empty_like(s.flags.flags[k])
        sig = np.empty(rev.n_components)
        assert point_trial(values, s.eps[k], deps[k], g, pk, rev.mode, rev.volumes0[k], out, flags, sig,
                           cell_responses_of(rev.kernels[k], values))
        np.testing.assert_allclose(sig, ref.sig[k], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(out, ref.cells.values[k], rtol=1e-12, atol=1e-15)


def test_the_2d_sets_keep_their_own_fabric_rows():
    geo, _ = Rev(SETS).kernel_inputs()
    assert geo.shape[0] == 2 and not np.allclose(geo[0, :, 3:], geo[1, :, 3:])  # weighted factors
    np.testing.assert_array_equal(geo[0, :, :3], geo[1, :, :3])  # the directions are shared


def test_a_rev_without_compiled_cells_has_no_kernel_inputs():
    rev = Rev(SETS[0])
    rev.kernels = None
    with pytest.raises(InputError, match="generic driver"):
        rev.kernel_inputs()
