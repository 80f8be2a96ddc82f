"""Test kinds as classes: a new kind of test plugs into the calibration as one class (here an
oedometer, defined in this file and never registered), the built-in kinds keep their names,
strings and identity, and a kind says what the model must reproduce (its observables)."""

from __future__ import annotations

import json
import math
import pickle

import numpy as np
import pytest

from hmodel import InputError, Params
from hmodel.calibrate import Kind, Test, fit
from hmodel.calibrate.kinds import BUILTIN, Drained
from hmodel.calibrate.model import Model, has_eps_v, residual_kinds, residuals
from hmodel.loading import run_oedometer, run_triaxial
from hmodel.rev import Sphere

BASE = Params(sliding_rhs="equilibrium")
TRUE = BASE.with_(phi_g=math.radians(28.0), alpha0=math.radians(50.0), kt_kn=0.5)
SPHERE = Sphere(order=9, n_azimuth=2, axis=(1.0, 0.0, 0.0))
KW = {"step": 1e-3, "iso_step": 1e-4, "sphere": SPHERE}


class Oedometer(Kind):
    """Oedometric compression of the 3D model, its lateral stress measured as q = σa − σr: the
    whole of a new kind of test."""

    value = "oedometer"
    dim = 3
    loading = "oedometric compression (ε22 = ε33 = 0), 3D"

    def run(self, sets, p0, strain, *, solver, sphere, step, iso_step):
        return run_oedometer(list(sets), list(p0), strain, sphere=sphere, solver=solver,
                             iso_step=iso_step, step=step, drop_failed=True)

    def observables(self):
        return ("q",)  # its εv is its axial strain: nothing the material decides


class Porosity(Oedometer):
    """A kind that asks the model for a curve it does not predict."""

    value = "porosity"

    def observables(self):
        return ("q", "n")


def _made_by(kind: Kind, p0: float, strain: float = 0.01) -> Test:
    """The test ``kind`` gives at TRUE, through its own run: every shear row."""
    r = kind.run([TRUE], [p0], strain, solver=None, sphere=SPHERE, step=1e-3, iso_step=1e-4)
    c, s = r.stage("consolidation"), r.stage("shear")
    e = kind.sign * (np.asarray(s["eps11"]) - c["eps11"][-1])
    return Test(kind, p0, kind.sign * e, np.asarray(s["q"]), np.asarray(s["eps_v"]) - c["eps_v"][-1])


@pytest.fixture(scope="module")
def tests():
    return [_made_by(Kind.TRIAXIAL_DRAINED, 1e5), _made_by(Oedometer(), 2e5)]


def test_a_kind_defined_outside_the_package_is_one_class_the_model_runs(tests):
    drained, oedo = tests
    assert oedo.kind == "oedometer" and oedo.kind.dim == 3 and not has_eps_v(oedo)
    # its rows are an oedometer's, not a triaxial test's: the lateral strain stays zero
    r = run_triaxial(TRUE, [2e5], 0.01, sphere=SPHERE, step=1e-3, iso_step=1e-4).stage("shear")
    assert not np.allclose(oedo.q, np.asarray(r["q"])[: len(oedo.q)], rtol=1e-3)
    model = Model(tuple(tests), **KW)
    assert model.dim == 3
    pred = model.predict([TRUE, TRUE.with_(kt_kn=0.3)])
    assert pred.ok.all()
    r = residuals(model.tests, pred)
    # drained: q then εv; the oedometer: q only (its observables), in the tests' order
    n1, n2 = len(drained.eps11), len(oedo.eps11)
    assert r.shape == (2, 2 * n1 + n2)
    assert residual_kinds(model.tests).tolist() == [True] * n1 + [False] * n1 + [True] * n2
    assert np.abs(r[0]).max() < 1e-8  # the truth's own curves (to the batched Newton's round-off)
    assert np.abs(r[1, 2 * n1:]).max() > 1e-2  # and the oedometer's q depends on kt/kn
    # another instance of the class is the same kind: the two oedometers run in one engine call
    again = _made_by(Oedometer(), 1e5)
    both = Model((oedo, again), **KW).predict([TRUE])
    assert np.abs(residuals((oedo, again), both)).max() < 1e-8


def test_a_calibration_fits_the_new_kind_as_the_built_in_ones(tests):
    cal = fit(tests, ("kt_kn",), bounds={"kt_kn": (0.2, 0.9)}, base=TRUE.with_(kt_kn=0.3), starts=1,
              search_rule=None, **KW)
    assert cal.fitted["kt_kn"] == pytest.approx(0.5, rel=1e-5)
    assert [t["kind"] for t in cal.to_dict()["tests"]] == ["triaxial-drained", "oedometer"]


def test_a_kind_is_not_registered_by_being_defined():
    assert Oedometer() not in list(Kind) and len(Kind) == len(BUILTIN) == 5
    with pytest.raises(InputError, match=r"^test kind must be drained or undrained \(2D\) or triaxial-drained, "
                                         r"triaxial-undrained, triaxial-extension \(3D\), got 'oedometer'$"):
        Kind.parse("oedometer")
    assert Kind.parse(Oedometer()) == "oedometer"  # an instance is its own kind


def test_a_kind_observing_what_the_model_does_not_predict_is_refused_in_one_line(tests):
    t = tests[1]
    odd = Test(Porosity(), t.p0, t.eps11, t.q)
    with pytest.raises(InputError, match=r"kind porosity observes n, which the model does not predict "
                                         r"\(it predicts q, eps_v\)$"):
        Model((odd,), **KW)


@pytest.mark.parametrize("kind", list(Kind))
def test_the_built_in_kinds_keep_their_names_strings_and_identity(kind):
    name = kind.value
    assert Kind(name) is kind and Kind.parse(name) is kind and getattr(Kind, kind.name) is kind
    assert kind == name and f"{kind}" == name and str(kind) == name and json.dumps(kind) == f'"{name}"'
    assert pickle.loads(pickle.dumps(kind)) is kind
    assert kind.observables() == (("q",) if kind.undrained else ("q", "eps_v"))
    assert kind.sign == (-1.0 if kind.extension else 1.0) and kind.dim == (3 if name.startswith("triaxial-") else 2)
    assert isinstance(kind, Kind) and isinstance(kind, str)


def test_members_by_name_and_a_subclass_instance_is_not_the_built_in():
    assert Kind.DRAINED == "drained" and Kind.TRIAXIAL_EXTENSION.extension
    assert [k.value for k in Kind] == ["drained", "undrained", "triaxial-drained", "triaxial-undrained",
                                       "triaxial-extension"]
    with pytest.raises(ValueError):
        Kind("oedometer")
    with pytest.raises(AttributeError):
        Kind.OEDOMETER  # noqa: B018
    other = Drained()
    assert other == Kind.DRAINED and other is not Kind.DRAINED and repr(other) == "Drained()"
    assert repr(Kind.DRAINED) == "Kind('drained')"
    assert pickle.loads(pickle.dumps(Oedometer())) == "oedometer"
