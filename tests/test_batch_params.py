"""Parameters per material point: a batch of different materials is its single runs, exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hmodel import InputError, Params
from hmodel.cell import ClosedFormSolver
from hmodel.cli.app import main
from hmodel.errors import PointFailure
from hmodel.loading import run_biaxial
from hmodel.params import check_batch, parse_point_assignments
from hmodel.rev import Rev

BASE = Params(n_theta=24)
# Every material parameter differs between the points, and so does the fabric.
SETS = [BASE.with_(kn=1.5e8, kt_kn=0.4, phi_g=math.radians(25), alpha0=math.radians(45)),
        BASE.with_(kn=3e8, kt_kn=0.8, phi_g=math.radians(35), alpha0=math.radians(58),
                   alpha_omega=0.4, beta_omega=math.radians(30), g2=1, sliding_rhs="equilibrium")]
COLUMNS = ("eps11", "eps22", "sig11", "sig22", "sig12", "q", "eps_v")


class Generic(ClosedFormSolver):
    """The closed form without its compiled kernel: the generic driver."""

    name = "closed-form (generic)"

    def kernel(self, params):
        return None


def _same(batch, singles):
    for b, single in enumerate(singles):
        got = batch.point(b)
        assert len(got) == len(single)
        for c in COLUMNS:
            a, e = np.asarray(got[c]), np.asarray(single[c])
            np.testing.assert_allclose(a, e, rtol=1e-9, atol=1e-9 * np.abs(e).max(), err_msg=c)


@pytest.mark.parametrize("undrained", [False, True])
@pytest.mark.parametrize("solver", [None, Generic()], ids=["compiled", "generic"])
def test_a_mixed_parameter_batch_equals_its_single_runs(undrained, solver):
    kw = dict(axial_strain=0.01, undrained=undrained, step=1e-3, iso_step=1e-4, solver=solver)
    batch = run_biaxial(SETS, [1e5, 2e5], **kw)
    singles = [run_biaxial(s, [p0], **kw) for s, p0 in zip(SETS, (1e5, 2e5))]
    _same(batch, singles)
    # the points really are different materials: their peak q / p0 differ by more than 10 %
    r0, r1 = (np.asarray(batch.point(b)["q"]).max() / p0 for b, p0 in ((0, 1e5), (1, 2e5)))
    assert abs(r0 - r1) > 0.1 * max(r0, r1)
    assert batch.meta["point_params"][1]["g2"] == 1


def test_one_pressure_is_broadcast_to_every_parameter_set():
    kw = dict(axial_strain=0.005, step=1e-3, iso_step=1e-4)
    _same(run_biaxial(SETS, 2e5, **kw), [run_biaxial(s, [2e5], **kw) for s in SETS])


def test_shared_parameters_must_agree():
    with pytest.raises(InputError, match="n_theta is shared"):
        Rev([BASE, BASE.with_(n_theta=36)])
    with pytest.raises(InputError, match="volume is shared"):
        check_batch([BASE, BASE.with_(volume="box")])
    with pytest.raises(InputError, match="2 parameter sets and 3 material points"):
        Rev(SETS).initial(3)


def test_comma_lists_give_one_set_per_value_and_single_values_are_shared():
    sets = parse_point_assignments(["phi_g=25,35", "alpha0=45,55", "kn=3e8"])
    assert [round(math.degrees(s.phi_g)) for s in sets] == [25, 35]
    assert [round(s.alpha0_deg) for s in sets] == [45, 55] and {s.kn for s in sets} == {3e8}
    with pytest.raises(InputError, match="equal lengths"):
        parse_point_assignments(["phi_g=25,35", "alpha0=45,50,55"])
    with pytest.raises(InputError, match="n_theta is shared"):
        parse_point_assignments(["n_theta=36,72"])
    with pytest.raises(InputError, match="empty value"):
        parse_point_assignments(["phi_g=25,"])


def test_cli_numbers_the_points_and_refuses_unequal_lists(tmp_path, capsys):
    out = tmp_path / "batch"
    assert main(["run", "biaxial", "--p0", "200kPa", "-p", "phi_g=25,35", "-p", "alpha0=45,55",
                 "-p", "n_theta=24", "--axial-strain", "0.005", "--out", str(out)]) == 0
    lines = (out / "result.csv").read_text().splitlines()
    points = {line.split(",")[0] for line in lines[1:]}
    assert points == {"0", "1"}
    one = tmp_path / "one"
    assert main(["run", "biaxial", "--p0", "200kPa", "-p", "phi_g=35", "-p", "alpha0=55", "-p", "n_theta=24",
                 "--axial-strain", "0.005", "--out", str(one)]) == 0
    mine = [line.split(",", 1)[1] for line in lines[1:] if line.startswith("1,")]
    theirs = [line.split(",", 1)[1] for line in (one / "result.csv").read_text().splitlines()[1:]]
    assert mine == theirs  # the same digits as its own single run
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert main(["run", "biaxial", "--p0", "100kPa,200kPa,300kPa", "-p", "phi_g=25,35", "--out", str(bad)]) == 1
    err = capsys.readouterr().err.strip()
    assert "2 material points" in err and "3" in err and "\n" not in err and not bad.exists()


# A loose material whose drained test at 100 kPa loses its stiffness near 2.3 % axial strain (every
# cell along some direction open: the mixed-control Newton meets a singular tangent).
LOOSE = Params(n_theta=360, kn=1288574896.34696, kt_kn=1.386663280819077,
               phi_g=math.radians(24.811546269265904), alpha0=math.radians(59.5873274062246))


@pytest.mark.parametrize("solver", [None, Generic()], ids=["compiled", "generic"])
def test_a_failed_point_is_dropped_and_the_others_go_on(solver):
    good = LOOSE.with_(alpha0=math.radians(45))
    kw = dict(axial_strain=0.04, step=1e-3, iso_step=1e-4, solver=solver)
    with pytest.raises(PointFailure) as err:
        run_biaxial([good, LOOSE], [1e5], **kw)
    assert err.value.points.tolist() == [1]  # the engine names the failed point
    batch = run_biaxial([good, LOOSE], [1e5], drop_failed=True, **kw)
    assert list(batch.meta["failed"]) == [1] and "singular" in batch.meta["failed"][1]
    _same(type(batch)(batch.point(0).columns, batch.meta), [run_biaxial(good, [1e5], **kw)])
    loose = batch.point(1).stage("shear")
    assert 0 < len(loose) < 40 and np.all(np.isfinite(loose["q"]))  # its rows stop at the failure
