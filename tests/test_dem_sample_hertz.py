"""``hmodel dem sample --contact hertz-mindlin``: DEM samples whose contacts follow YADE's
Hertz-Mindlin law (stiffnesses growing with the normal force, from the grains' G and nu). The
settings' refusals, the request and the engines YADE builds (read without YADE), and one tiny
real run whose exported contacts obey the Hertz law."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from hmodel.dem.sample import SampleSettings, run_sample
from hmodel.dem.sample import run as sample_run
from hmodel.dem.yade.scripts import common
from hmodel.errors import InputError

G, NU = 2.9e10, 0.2
HERTZ = ["--contact", "hertz-mindlin", "--shear-modulus", "29GPa", "--poisson", "0.2"]


def _hertz_force(young, poisson, r1, r2, overlap):
    """fn = 4/3 E* sqrt(R) d^1.5, E* = E / (2 (1 - nu^2)), R = r1 r2 / (r1 + r2) (Johnson,
    Contact Mechanics, 1985, eq. 4.22, for two grains of one material)."""
    e_star = young / (2.0 * (1.0 - poisson ** 2))
    return 4.0 / 3.0 * e_star * np.sqrt(r1 * r2 / (r1 + r2)) * overlap ** 1.5


# -- settings and command line ----------------------------------------------------------------

@pytest.mark.parametrize("args, message", [
    (["--contact", "hertz"], "--contact must be one of linear, hertz-mindlin, got 'hertz'"),
    (["--contact", "hertz-mindlin"], "needs the grains' --shear-modulus and --poisson"),
    (["--contact", "hertz-mindlin", "--shear-modulus", "29GPa"], "needs the grains' --poisson"),
    (["--contact", "hertz-mindlin", "--poisson", "0.2"], "needs the grains' --shear-modulus"),
    ([*HERTZ[:2], "--shear-modulus", "0", "--poisson", "0.2"], "--shear-modulus must be a positive modulus"),
    ([*HERTZ[:2], "--shear-modulus", "-29GPa", "--poisson", "0.2"], "--shear-modulus must be a positive modulus"),
    ([*HERTZ[:2], "--shear-modulus", "29 bananas", "--poisson", "0.2"], "--shear-modulus must be a positive modulus"),
    ([*HERTZ[:2], "--shear-modulus", "inf", "--poisson", "0.2"], "--shear-modulus must be a positive modulus"),
    ([*HERTZ[:4], "--poisson", "0.5"], "--poisson must lie in (-1, 0.5), got 0.5"),
    ([*HERTZ[:4], "--poisson", "-1"], "--poisson must lie in (-1, 0.5), got -1"),
    ([*HERTZ[:4], "--poisson", "nan"], "--poisson must lie in (-1, 0.5), got nan"),
    (["--shear-modulus", "29GPa"], "--shear-modulus sets the Hertz-Mindlin law: add --contact hertz-mindlin"),
    (["--shear-modulus", "29GPa", "--poisson", "0.2"], "--shear-modulus and --poisson set the Hertz-Mindlin law"),
    ([*HERTZ, "--kn", "1e8"], "--kn and --kt-kn set the linear law"),
    ([*HERTZ, "--kt-kn", "0.5"], "--kn and --kt-kn set the linear law"),
])
@pytest.mark.parametrize("dim", [2, 3])
def test_bad_contact_options_are_one_line_errors_and_write_nothing(tmp_path, monkeypatch, cli, dim, args,
                                                                   message):
    monkeypatch.setenv("HMODEL_YADE", str(tmp_path / "no-such-yade"))  # refused before YADE
    out = tmp_path / "out"
    cli.refuses(["dem", "sample", "--dim", dim, *args, "--out", out], message, out)
    assert list(tmp_path.iterdir()) == []


def test_the_settings_record_the_law_and_the_api_refuses_alike():
    s = SampleSettings(dim=3, disks=120, contact="hertz-mindlin", shear_modulus=G, poisson=NU)
    assert s.young == 2.0 * G * (1.0 + NU)
    assert s.to_dict()["contact"] == "hertz-mindlin" and s.to_dict()["shear_modulus"] == G
    linear = SampleSettings(dim=3, disks=120)
    assert (linear.contact, linear.shear_modulus, linear.poisson, linear.young) == ("linear", None, None, None)
    with pytest.raises(InputError, match="--poisson must lie"):
        SampleSettings(dim=3, disks=120, contact="hertz-mindlin", shear_modulus=G, poisson=0.7)
    with pytest.raises(InputError, match="--contact must be one of"):
        SampleSettings(contact="Hertz-Mindlin")


def _captured_request(monkeypatch, settings, kind="triaxial-drained"):
    """The request run_test sends to YADE (YADE not started)."""
    seen = {}

    class Stop(Exception):
        pass

    def fake_run(task, spec, timeout):
        seen.update(task=task, spec=spec)
        raise Stop

    monkeypatch.setattr(sample_run, "run", fake_run)
    with pytest.raises(Stop):
        sample_run.run_test(settings, kind, 1e5)
    return seen["spec"]


def test_the_request_carries_the_law_and_the_linear_request_is_unchanged(monkeypatch):
    hertz = _captured_request(monkeypatch, SampleSettings(dim=3, disks=120, contact="hertz-mindlin",
                                                          shear_modulus=G, poisson=NU))
    assert (hertz["contact"], hertz["young"], hertz["poisson"]) == ("hertz-mindlin", 2 * G * 1.2, NU)
    linear = _captured_request(monkeypatch, SampleSettings(dim=3, disks=120))
    # the linear law's request: the keys it has always had, no contact law among them
    assert not {"contact", "young", "poisson"} & set(linear)
    assert {k: v for k, v in hertz.items() if k not in ("contact", "young", "poisson")}.keys() == linear.keys()


def test_a_folder_of_linear_contacts_is_not_resumed_as_hertz_and_old_folders_resume(tmp_path, monkeypatch):
    """A sample.json written before the contact law was a setting reads as linear contacts."""
    out = tmp_path / "s"
    out.mkdir()
    old = {k: v for k, v in SampleSettings(dim=3, disks=120).to_dict().items()
           if k not in ("contact", "shear_modulus", "poisson")}
    (out / "sample.json").write_text(json.dumps({"settings": old, "yade_version": "x", "tests": {}}))
    hertz = SampleSettings(dim=3, disks=120, contact="hertz-mindlin", shear_modulus=G, poisson=NU)
    with pytest.raises(InputError, match="--contact, --poisson, --shear-modulus"):
        run_sample(hertz, [1e5], "triaxial-drained", out)
    monkeypatch.setattr(sample_run, "run_test", lambda *a: (_ for _ in ()).throw(RuntimeError("resumed")))
    with pytest.raises(RuntimeError, match="resumed"):  # the same (linear) sample: accepted
        run_sample(SampleSettings(dim=3, disks=120), [1e5], "triaxial-drained", out)


# -- the YADE side, read without YADE ---------------------------------------------------------

def _fake_wrapper():
    """A stand-in for ``yade.wrapper``: each functor is (its class name, its arguments)."""
    def functor(name):
        return lambda *args, **kwargs: (name, args, kwargs)

    names = ("Ip2_FrictMat_FrictMat_FrictPhys", "Ip2_FrictMat_FrictMat_MindlinPhys", "MatchMaker",
             "Law2_ScGeom_FrictPhys_CundallStrack", "Law2_ScGeom_MindlinPhys_Mindlin")
    return SimpleNamespace(**{n: functor(n) for n in names})


def test_yade_gets_the_hertz_mindlin_engines_and_the_linear_ones_unchanged():
    w = _fake_wrapper()
    young, poisson, ip2, law2 = common.contact_law(w, {"contact": "hertz-mindlin", "young": 7e10,
                                                       "poisson": 0.2, "kn": 2e8, "kt_kn": 0.5}, 4 / 3)
    assert (young, poisson, ip2[0], law2[0]) == (7e10, 0.2, "Ip2_FrictMat_FrictMat_MindlinPhys",
                                                 "Law2_ScGeom_MindlinPhys_Mindlin")
    young, poisson, ip2, law2 = common.contact_law(w, {"kn": 2e8, "kt_kn": 0.5}, 4 / 3)
    assert (young, poisson, law2[0]) == (2e8 / (4 / 3), 0.5, "Law2_ScGeom_FrictPhys_CundallStrack")
    assert ip2 == ("Ip2_FrictMat_FrictMat_FrictPhys", (),
                   {"kn": ("MatchMaker", (), {"algo": "val", "val": 2e8}),
                    "ks": ("MatchMaker", (), {"algo": "val", "val": 1e8})})


def test_time_step_stiffness_is_the_hertz_tangent_at_the_margin_force():
    e, nu, r_max, scale = 7e10, 0.2, 4 / 3, 1e5 * (8 / 3) ** 2
    force = common.HERTZ_FORCE_MARGIN * scale
    # the overlap of two largest grains at that force, then dfn/dd by a central difference
    d = (force / _hertz_force(e, nu, r_max, r_max, 1.0)) ** (2.0 / 3.0)
    h = 1e-6 * d
    k = (_hertz_force(e, nu, r_max, r_max, d + h) - _hertz_force(e, nu, r_max, r_max, d - h)) / (2 * h)
    got = common.time_step_stiffness({"contact": "hertz-mindlin", "young": e, "poisson": nu}, r_max, scale)
    assert got == pytest.approx(k, rel=1e-8)
    assert common.time_step_stiffness({"kn": 2e8}, r_max, scale) == 2e8


# -- one tiny real run ------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.yade
def test_a_tiny_hertz_sample_has_hertz_contacts(tmp_path):
    """A 3D sample of 120 spheres (soft grains, for few time steps) sheared to 0.2 %: every
    exported contact's normal force is the Hertz force of its overlap, and the sample carries q."""
    g, nu = 2e8, 0.25
    settings = SampleSettings(dim=3, disks=120, contact="hertz-mindlin", shear_modulus=g, poisson=nu,
                              axial_strain=0.002, rows=2, inertial_number=1e-3)
    meta = run_sample(settings, [1e5], "triaxial-drained", tmp_path / "s")
    assert meta["settings"]["contact"] == "hertz-mindlin"
    rec = meta["tests"]["triaxial-drained_100kPa"]
    young = 2 * g * (1 + nu)
    with np.load(tmp_path / "s" / "triaxial-drained_100kPa.npz") as z:
        radii, contacts, rows = z["radii"], z["final_contacts"], z["rows"]
    assert len(contacts) > 100
    i, j = contacts[:, 0].astype(int), contacts[:, 1].astype(int)
    gap = np.linalg.norm(contacts[:, 6:9], axis=1)
    overlap = radii[i] + radii[j] - gap
    expected = _hertz_force(young, nu, radii[i], radii[j], overlap)
    # the exported positions are a step later than the overlaps YADE's forces come from: 3 %
    assert np.allclose(contacts[:, 2], expected, rtol=0.03)
    # fn / sqrt(R) against the overlap: the power 1.5 of Hertz (a linear law's would be 1)
    reduced = contacts[:, 2] / np.sqrt(radii[i] * radii[j] / (radii[i] + radii[j]))
    assert np.polyfit(np.log(overlap), np.log(reduced), 1)[0] == pytest.approx(1.5, abs=0.03)
    # drained: the lateral stresses held at p0 while q builds up
    assert rows[-1, 3] - 0.5 * (rows[-1, 4] + rows[-1, 5]) > 0.05e5
    assert rec["max_lateral_stress_error"] < 0.05


# -- the benchmark's measures and the page generated from them -----------------------------

def test_the_critical_state_measure_finds_one_line_and_one_m():
    from benchmarks.dem.granular import critical_state

    def end(p, e, m, dil=0.0):
        return {"kind": "triaxial-drained", "end": {"p": p, "e": e, "M": m, "dilatancy": dil}}

    line = {f"t{k}": end(p, 0.9 - 0.05 * math.log(p / 1e3), 1.2) for k, p in enumerate((1e5, 2e5, 4e5))}
    cs = critical_state(line, 1e3)
    assert cs["Gamma"] == pytest.approx(0.9) and cs["lambda"] == pytest.approx(0.05)
    assert cs["M"] == pytest.approx(1.2) and cs["measure"]["critical_state"]
    off = dict(line, t3=end(3e5, 0.9 - 0.05 * math.log(300) + 0.04, 1.2))
    assert not critical_state(off, 1e3)["measure"]["one_line"]
    assert not critical_state(dict(line, t3=end(3e5, 0.9 - 0.05 * math.log(300), 1.3)), 1e3)["measure"]["one_M"]
    assert not critical_state(dict(line, t3=end(3e5, 0.9 - 0.05 * math.log(300), 1.2, -0.08)),
                              1e3)["measure"]["zero_dilatancy"]


def test_the_docs_tables_are_generated_from_the_benchmark_json():
    """docs/dem.md's Hertz-Mindlin tables are the benchmark's rendering of its JSON (no number
    copied by hand), and its kept CSVs are tests that ``hmodel calibrate --data`` reads."""
    from benchmarks.dem.granular import DOCS, HERE, MARKERS, render
    from hmodel.calibrate import parse_data_spec

    for name, block_name in (("granular.json", "granular"), ("granular_linear.json", "granular-linear")):
        rec = json.loads((HERE / name).read_text())
        begin, end = (m.format(block_name) for m in MARKERS)
        block = DOCS.read_text().split(begin, 1)[1].split(end, 1)[0]
        assert block == "\n" + render(rec)
        for t in rec["tests"].values():
            test = parse_data_spec(t["data"])
            assert test.e0 == pytest.approx(t["e0"], rel=1e-5) and len(test.q) > 10
