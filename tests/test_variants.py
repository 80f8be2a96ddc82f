"""The named variants' mechanisms (``--model hertz``, ``--model rebirth``): applied to every
parameter set and fitted by their own parameters."""

import pytest

from hmodel import Params
from hmodel.calibrate import Test, fit
from hmodel.errors import InputError
from hmodel.variants import VARIANTS, get_variant


def test_published_and_density_change_nothing():
    p = Params(kn=3e8, renewal="rebirth")
    assert get_variant("published").apply(p) is p and get_variant("density").apply(p) is p


@pytest.mark.parametrize("name, contact, renewal", [("hertz", "hertz-mindlin", "none"),
                                                     ("rebirth", "hertz-mindlin", "rebirth")])
def test_mechanism_variants_switch_their_options_on(name, contact, renewal):
    v = get_variant(name)
    p = v.initial_params(Params(), 3, e0=0.8, e_ref=0.8)
    assert (p.contact, p.renewal) == (contact, renewal)
    assert p.alpha0 == pytest.approx(Params().alpha0)  # α0 at e_ref
    assert v.fitted == ("shear_modulus", "poisson", "phi_g", "alpha0")


def test_every_variant_is_listed(cli, monkeypatch):
    monkeypatch.setenv("COLUMNS", "300")  # a table cell wrapped at the terminal's width is not one string
    code, out, _ = cli("models")
    assert code == 0
    for name in VARIANTS:
        assert name in out
    assert "contact=hertz-mindlin" in out


def test_fitting_a_parameter_the_contact_law_does_not_read_is_refused():
    t = Test("triaxial-drained", 100e3, [0.0, 0.01], [0.0, 1e5], e0=0.8)
    with pytest.raises(InputError, match="kn is not read by hertz-mindlin contacts: fit shear_modulus and poisson"):
        fit([t], ("kn", "alpha0"), model="hertz", starts=1)
    with pytest.raises(InputError, match="shear_modulus is not read by linear contacts: fit kn and kt_kn"):
        fit([t], ("shear_modulus",), model="density", starts=1)


def test_cli_run_with_a_mechanism_variant(cli, tmp_path):
    """``--model rebirth`` runs what its options say: the same numbers as naming them with -p,
    other numbers than the published model's."""
    common = ("run", "triaxial", "--p0", "100kPa", "--axial-strain", "0.002", "--order", "5", "--azimuths", "1")
    csv = {}
    for key, extra in (("variant", ("--model", "rebirth")),
                       ("params", ("-p", "contact=hertz-mindlin", "-p", "renewal=rebirth")),
                       ("published", ())):
        code, _, err = cli(*common, *extra, "--out", tmp_path / key)
        assert code == 0, err
        csv[key] = (tmp_path / key / "result.csv").read_text()
    assert csv["variant"] == csv["params"]
    assert csv["variant"] != csv["published"]


def test_variants_travel_to_worker_processes():
    import pickle

    for v in VARIANTS.values():
        assert pickle.loads(pickle.dumps(v)) == v


def test_failure_surface_takes_a_variant(cli, tmp_path):
    """``failure-surface --model sand`` is the surface of the variant's mechanisms (as -p names them)."""
    common = ("failure-surface", "--lode", "0", "--order", "5", "--azimuths", "1", "--max-strain", "0.05")
    tables = {}
    for key, extra in (("variant", ("--model", "sand")), ("params", ("-p", "contact=hertz-mindlin")),
                       ("published", ())):
        code, _, err = cli(*common, *extra, "--out", tmp_path / key)
        assert code == 0, err
        tables[key] = (tmp_path / key / "failure_surface.csv").read_text()
    assert tables["variant"] == tables["params"] != tables["published"]
