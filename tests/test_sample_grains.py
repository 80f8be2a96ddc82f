"""The grains of a DEM sample (hmodel.dem.sample.geometry): disks and spheres hold everything that
differs between a 2D and a 3D sample."""

import numpy as np
import pytest

from hmodel.dem.sample import Disks, SampleSettings, SampleState, SampleTest, Spheres, grains
from hmodel.errors import InputError


def test_a_sample_asks_its_grains():
    assert isinstance(grains(2), Disks) and isinstance(grains(3), Spheres)
    assert SampleSettings(dim=3, disks=200).grains is grains(3)
    with pytest.raises(InputError, match=r"^--dim must be 2 \(disks\) or 3 \(spheres\), got 4$"):
        grains(4)


@pytest.mark.parametrize("dim, distribution", [(2, "uniform"), (2, "equal-area"), (3, "uniform"),
                                               (3, "equal-volume")])
def test_mean_solid_is_that_of_the_drawn_radii(dim, distribution):
    g, a, b = grains(dim), 0.5, 1.5
    u = (np.arange(200_000) + 0.5) / 200_000
    r = a + (b - a) * u if distribution == "uniform" else g.graded_radii(a, b, u)
    assert r.min() >= a and r.max() <= b
    assert g.mean_solid(a, b, distribution) == pytest.approx(np.mean(g.solid(r)), rel=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_forces_are_the_contact_rows_normal_and_tangential_forces(dim):
    g = grains(dim)
    c = np.random.default_rng(dim).normal(size=(20, len(g.contact_columns)))
    e = c[:, -dim:] / np.linalg.norm(c[:, -dim:], axis=1)[:, None]
    if dim == 3:  # a row's tangential force is normal to its branch
        c[:, 3:6] -= np.einsum("ca,ca->c", c[:, 3:6], e)[:, None] * e
    st = SampleState(cell=(5.0,) * dim, radii=np.ones(4), positions=np.zeros((4, dim)), contacts=c)
    f = st.forces()
    np.testing.assert_allclose(np.einsum("ca,ca->c", f, e), c[:, 2], rtol=1e-12, atol=1e-12)
    tangential = c[:, 3, None] * np.column_stack([e[:, 1], -e[:, 0]]) if dim == 2 else c[:, 3:6]
    np.testing.assert_allclose(f - c[:, 2, None] * e, tangential, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_tests_csv_has_its_grains_columns(dim, tmp_path):
    g = grains(dim)
    st = SampleState(cell=(5.0,) * dim, radii=np.ones(4), positions=np.zeros((4, dim)),
                     contacts=np.ones((3, len(g.contact_columns))))
    rows = np.random.default_rng(0).normal(size=(3, len(g.row_columns)))
    test = SampleTest(kind=g.kinds[0], p0=1e5, rows=rows, consolidated=st, final=st, info={})
    assert tuple(test.table()) == g.csv_columns
    test.write_csv(tmp_path / "t.csv")
    assert (tmp_path / "t.csv").read_text().split("\n", 1)[0] == ",".join(g.csv_columns)
