import math

import pytest

from hmodel import InputError, Params


def test_defaults_are_table_1_1():
    p = Params()
    assert (p.kn, p.kt_kn, p.n_theta, p.volume, p.g2) == (2e8, 0.5, 360, "hexagon", 0)
    assert math.isclose(math.degrees(p.phi_g), 30) and math.isclose(p.alpha0_deg, 45)
    assert p.kt == pytest.approx(1e8)


def test_initial_lengths_follow_eq_1_2():
    p = Params(alpha0=math.radians(60), radius=0.5)
    assert p.l10 == pytest.approx(1 + 2 * math.cos(math.radians(60)))
    assert p.l20 == pytest.approx(2 * math.sin(math.radians(60)))


@pytest.mark.parametrize("assign, word", [
    ("kn=-1", "kn"), ("kt_kn=0", "kt_kn"), ("phi_g=0", "phi_g"), ("phi_g=90", "phi_g"),
    ("alpha0=30", "alpha0"), ("alpha0=91", "alpha0"), ("alpha_omega=1.5", "alpha_omega"),
    ("n_theta=0", "n_theta"), ("n_theta=2.5", "n_theta"), ("volume=sphere", "volume"),
    ("g2=2", "g2"), ("kn=nan", "kn"), ("kn=abc", "kn"), ("radius=-1", "radius"),
    ("sliding_rhs=foo", "sliding_rhs"), ("nope=1", "nope"), ("kn", "NAME=VALUE"),
])
def test_bad_parameters_are_named(assign, word):
    with pytest.raises(InputError) as e:
        Params.parse_assignments([assign])
    assert word in str(e.value) and "\n" not in str(e.value)


def test_angles_in_degrees_from_strings():
    p = Params.parse_assignments(["alpha0=50", "beta_omega=30", "volume=box", "n_theta=72"])
    assert p.alpha0 == pytest.approx(math.radians(50)) and p.beta_omega == pytest.approx(math.radians(30))
    assert p.volume == "box" and p.n_theta == 72
    assert p.to_dict()["alpha0"] == pytest.approx(50)
