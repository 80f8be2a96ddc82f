"""The contact-fabric benchmark's judge (benchmarks/model3d/contact_fabric.py,
docs/notes/2026-12-07-contact-fabric.md)."""

import numpy as np
import pytest

import benchmarks.model3d.contact_fabric as bench
from hmodel.rev.contacts import Fabric, fabric, grain_contacts


def test_the_judge_runs_a_calibrated_variant_and_measures_its_distance_to_the_dem(monkeypatch):
    monkeypatch.setattr(bench, "JUDGED", ("axisym",))
    # a DEM "sample" of three contacts along the axes: its fabric is what the REV is compared with
    u = np.eye(3)
    f = fabric(grain_contacts(u, u)).as_dict()
    rows = bench.judge_part({"dense-hertz": {"final": f}, "loose-hertz": {"final": f}}, strain=0.02)
    assert [r["sample"] for r in rows] == ["dense-hertz", "loose-hertz"]
    for r in rows:
        assert r["variant"] == "axisym" and 0.0 < r["rms_dq_judge"] < 1.0
        assert r["eps11"] == pytest.approx(0.02)
        # the loose specimen starts looser: a larger opening angle (the variant maps e0 to alpha0)
        d = r["distance_to_dem"]
        assert all(0.0 <= d[k] <= 1.0 for k in bench.SHARES)
        ref = Fabric.from_dict(f)
        assert d["contacts"] == pytest.approx(Fabric.from_dict(r["final"]).distance(ref, "contacts"))
    assert rows[1]["alpha0_deg"] > rows[0]["alpha0_deg"]
