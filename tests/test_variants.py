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


@pytest.mark.parametrize("name, contact, renewal, cross", [("hertz", "hertz-mindlin", "none", "none"),
                                                            ("rebirth", "hertz-mindlin", "rebirth", "none"),
                                                            ("mix", "hertz-mindlin", "mix", "none"),
                                                            ("cross", "hertz-mindlin", "none", "frictionless")])
def test_mechanism_variants_switch_their_options_on(name, contact, renewal, cross):
    v = get_variant(name)
    p = v.initial_params(Params(), 3, e0=0.8, e_ref=0.8)
    assert (p.contact, p.renewal, p.cross_contacts) == (contact, renewal, cross)
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
    for key, extra in (("variant", ("--model", "sand")), ("params", ("-p", "contact=hertz-mindlin", "-p", "renewal=mix",
                                                                       "-p", "lateral=axisymmetric")),
                       ("published", ())):
        code, _, err = cli(*common, *extra, "--out", tmp_path / key)
        assert code == 0, err
        tables[key] = (tmp_path / key / "failure_surface.csv").read_text()
    assert tables["variant"] == tables["params"] != tables["published"]


@pytest.mark.parametrize("spread", [0.0, 0.3])
def test_the_cross_variant_searches_only_where_the_densest_hexagons_do_not_overlap(spread):
    """Its α0 range at e_ref starts where the densest test's lowest opening angle is 45°
    (below, an unloaded bi-hexagon's hexagons overlap, and the cell refuses the option)."""
    import math

    from hmodel.cell.bihex import check_params
    from hmodel.rev.density import alpha0_for_void_ratio

    base = Params(alpha0_spread=spread)
    e0s, e_ref = (0.60, 0.75, 0.80), 0.72
    low, top = get_variant("cross").default_bounds(base, 3, e0s, e_ref)["alpha0"]
    assert low > get_variant("hertz").default_bounds(base, 3, e0s, e_ref)["alpha0"][0] and low < top

    def lowest_angle(a0_ref):
        a = alpha0_for_void_ratio(base.with_(alpha0=math.radians(a0_ref)), 3, min(e0s), e_ref)
        return math.degrees(a - spread * min(a - math.pi / 6, math.pi / 2 - a))

    # at the bound the densest cells open at 45 deg (to the bound's rounding to 0.1 deg), and the
    # bi-hexagon takes the option there; 0.2 deg below it refuses it
    assert lowest_angle(low) == pytest.approx(45.0, abs=0.2) and lowest_angle(low) >= 45.0 - 1e-9
    dense = get_variant("cross").initial_params(base.with_(alpha0=math.radians(low)), 3, e0=min(e0s), e_ref=e_ref)
    check_params(dense)
    with pytest.raises(InputError, match="45 deg"):
        check_params(get_variant("cross").initial_params(base.with_(alpha0=math.radians(low - 0.2)), 3,
                                                         e0=min(e0s), e_ref=e_ref))


def test_the_cross_variant_refuses_densities_it_cannot_span():
    with pytest.raises(InputError, match="cannot span void ratios"):
        get_variant("cross").default_bounds(Params(), 3, (0.30, 1.2), 0.8)
    with pytest.raises(InputError, match="cannot span void ratios"):  # 45 deg is not in the cells' range
        get_variant("cross").default_bounds(Params(alpha0_spread=0.7), 3, (0.60, 0.75), 0.72)
