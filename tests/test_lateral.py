"""The bi-hexagon's lateral strain about its axis (``lateral="axisymmetric"``, docs/mechanisms.md,
"Lateral strain about the cell's axis"): the localization it gives, the closed cell it keeps,
the two drivers, the azimuths, the 2D cell and the batch."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.errors import InputError
from hmodel.loading import Recorder, Segment, consolidate, run_segment, run_triaxial
from hmodel.rev import Rev3D, Sphere
from hmodel.rev import rev3d
from hmodel.rev.rev3d import lateral_projector, projector

SMALL = Sphere(order=11, n_azimuth=2)
BASE = Params(sliding_rhs="equilibrium", alpha0=math.radians(50.0))


def test_the_axisymmetric_localization_is_the_mean_lateral_strain_and_keeps_the_trace():
    rng = np.random.default_rng(3)
    frames, _ = SMALL.frames()
    proj = projector(frames)
    deps = rng.normal(size=6)
    e = proj @ deps  # (C, 3): the strains along n, t1, t2 of every cell
    axi = lateral_projector(proj, "axisymmetric") @ deps
    assert lateral_projector(proj, "affine") is proj
    assert np.array_equal(axi[:, 0], e[:, 0])
    assert np.allclose(axi[:, 1], 0.5 * (e[:, 1] + e[:, 2]), rtol=0, atol=1e-14)
    assert np.array_equal(axi[:, 1], axi[:, 2])
    # an orthonormal frame's three normal strains sum to the trace, whatever the frame
    trace = deps[0] + deps[1] + deps[2]
    assert np.allclose(axi.sum(axis=1), trace, atol=1e-13) and np.allclose(e.sum(axis=1), trace, atol=1e-13)
    # a strain that is not axisymmetric about some cell's axis: affine cells see unequal laterals
    assert np.abs(e[:, 1] - e[:, 2]).max() > 0.1


def _triaxial(lateral, compiled=None, strain=0.03):
    params = BASE.with_(lateral=lateral)
    return run_triaxial(params, [2e5], strain, sphere=SMALL, step=1e-3, compiled=compiled)


def test_a_bihexagon_stays_one_cell_of_two_equal_hexagons_and_not_without():
    """With the mean lateral strain both hexagons of every bi-hexagon take the same increments
    from the same start, so they stay equal (the cell's stress is axisymmetric about its axis,
    the work-conjugate of the strain it sees); with affine laterals a tilted cell's two
    hexagons part in a triaxial test (one leaves contact)."""
    for lateral, equal in (("axisymmetric", True), ("affine", False)):
        rev = Rev3D(BASE.with_(lateral=lateral), SMALL)
        state = consolidate(rev, np.array([2e5]))
        values = np.array([[0.03, 2e5, 2e5, 0.0, 0.0, 0.0]])
        out = run_segment(rev, state, Segment((False, True, True, False, False, False), np.eye(6), values, 30,
                                              "shear"), Recorder())
        v = out.state.cells.values[0]
        force = np.abs(v[:, 3:6]).max()
        same = (np.allclose(v[:, :3], v[:, 8:11], rtol=0, atol=1e-12)
                and np.allclose(v[:, 3:6], v[:, 11:14], rtol=0, atol=1e-9 * force))
        assert same == equal, lateral


def test_the_compiled_and_the_generic_drivers_agree():
    a = _triaxial("axisymmetric")
    b = _triaxial("axisymmetric", compiled=False)
    assert np.allclose(a["q"], b["q"], rtol=1e-7, atol=1e-3) and np.allclose(a["eps_v"], b["eps_v"], atol=1e-10)
    assert not np.allclose(a["q"], _triaxial("affine")["q"], rtol=1e-3)  # the option does change the path


def test_the_2d_cell_has_one_lateral_length_and_a_batch_one_value():
    """The 2D H-cell's one lateral length is its own mean: either value is the published 2D
    model, bit for bit (so a variant that switches it on runs in 2D too)."""
    from hmodel.loading import run_biaxial

    a = run_biaxial(Params(n_theta=36, lateral="axisymmetric"), [2e5], 0.02)
    b = run_biaxial(Params(n_theta=36), [2e5], 0.02)
    assert all(np.array_equal(a[c], b[c], equal_nan=True) for c in ("q", "p", "eps_v"))
    with pytest.raises(InputError, match="lateral"):
        Rev3D([BASE, BASE.with_(lateral="axisymmetric")], SMALL)
    with pytest.raises(InputError, match="parameter lateral must be one of affine, axisymmetric"):
        Params(lateral="radial")


@pytest.mark.parametrize("mechanisms", [{}, {"contact": "hertz-mindlin", "renewal": "mix"},
                                        {"cross_contacts": "frictionless"}],
                         ids=["lateral", "sand", "cross"])
def test_the_azimuths_of_a_direction_then_repeat_one_cell(monkeypatch, mechanisms):
    """The mean lateral strain is the trace of the strain across n halved, the same at every
    azimuth about n; the cells of one direction are then one cell, whose stress s (I - n n)
    the azimuths' dyads sum to whatever their number: the REV holds one azimuth per direction
    and answers as with every azimuth held (with affine laterals the azimuths differ). The sides
    are held equal: with free sides the sand's REV bifurcates and round-off picks the path
    (test_radial.py)."""
    sphere = Sphere(order=11, n_azimuth=3)
    n_dirs = Sphere(order=11, n_azimuth=1).n_cells

    def q(lateral):
        params = BASE.with_(lateral=lateral, **mechanisms)
        return run_triaxial(params, [2e5], 0.02, sphere=sphere, step=1e-3, radial="equal")["q"]
    assert Rev3D(BASE.with_(lateral="axisymmetric"), sphere).n_cells == n_dirs
    assert Rev3D(BASE, sphere).n_cells == 3 * n_dirs
    one, affine = q("axisymmetric"), q("affine")
    monkeypatch.setattr(rev3d, "cell_sphere", lambda sphere, lateral, solver: sphere)
    assert Rev3D(BASE.with_(lateral="axisymmetric"), sphere).n_cells == 3 * n_dirs
    assert np.allclose(one, q("axisymmetric"), rtol=1e-9, atol=1e-3)
    assert np.array_equal(affine, q("affine"), equal_nan=True)
    assert not np.allclose(affine, run_triaxial(BASE.with_(**mechanisms), [2e5], 0.02, step=1e-3,
                                                radial="equal", sphere=Sphere(order=11, n_azimuth=1))["q"],
                              rtol=1e-3)
