"""Stability indicators that agree: the bifurcation domain is entered no later than the loss of
controllability (the loading direction is itself a probe direction, Hill's criterion)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cli.app import main
from hmodel.loading import Program
from hmodel.stability import along_biaxial, along_program, loading_work

LOOSE, DENSE = math.radians(60), math.radians(45)


@pytest.mark.parametrize("alpha0", [LOOSE, DENSE], ids=["loose", "dense"])
@pytest.mark.parametrize("undrained", [True, False], ids=["undrained", "drained"])
def test_entry_never_after_loss_of_controllability(alpha0, undrained):
    ps = along_biaxial(Params(n_theta=90, alpha0=alpha0), 2e5, 0.05, undrained=undrained, n_probes=36)
    assert math.isfinite(ps.bifurcation)
    if math.isfinite(ps.controllability):
        assert ps.bifurcation <= ps.controllability
        assert ps.bifurcation_step <= ps.controllability_step
    if alpha0 == LOOSE:  # static liquefaction (undrained) and a peak of sig11 (drained)
        assert math.isfinite(ps.controllability)


def test_loading_increment_counts_as_a_probe_from_its_start():
    """The entry found by the loading increment is the start of the first increment whose d²W,
    computed here from the result table, is <= 0."""
    ps = along_biaxial(Params(n_theta=90, alpha0=LOOSE), 2e5, 0.01, undrained=True, n_probes=12,
                       every=50)
    r = ps.result
    eps = np.column_stack([r["eps11"], r["eps22"], r["eps12"]])
    sig = np.column_stack([r["sig11"], r["sig22"], r["sig12"]])
    first_shear = int(np.flatnonzero(r["stage"] == "shear")[0])
    _, w = loading_work(eps[first_shear - 1:], sig[first_shear - 1:])
    i = int(np.flatnonzero(w <= 0)[0])
    assert ps.bifurcation_by == "loading increment"
    assert ps.bifurcation_step == r["step"][first_shear - 1 + i]
    # without it, probes every 50th state find the domain later than the loading did, or never
    late = along_biaxial(Params(n_theta=90, alpha0=LOOSE), 2e5, 0.01, undrained=True, n_probes=12,
                         every=50, loading_probe=False, near=-2)
    assert not late.bifurcation <= ps.bifurcation


def test_probe_magnitude_of_the_increment_triggers_the_finite_events():
    """Loose undrained, probes at every state, the loading increment not counted: probes as
    large as the loading increment (1.4e-4) open contacts that probes of 1e-5 do not, and find
    the domain earlier; both no later than the loss of controllability."""
    P = Params(n_theta=360, alpha0=LOOSE)
    small = along_biaxial(P, 2e5, 0.004, undrained=True, magnitude=1e-5, every=1, n_probes=72,
                          loading_probe=False)
    tied = along_biaxial(P, 2e5, 0.004, undrained=True, every=1, n_probes=72, loading_probe=False)
    assert math.isfinite(small.controllability) and small.controllability == tied.controllability
    np.testing.assert_allclose(tied.check_magnitude[1:], math.sqrt(2) * 1e-4, rtol=1e-9)
    assert tied.bifurcation < small.bifurcation <= small.controllability


def test_stability_of_a_cyclic_program(tmp_path, capsys):
    text = ('[params]\nn_theta = 36\nalpha0 = 60\n[[stage]]\npreset = "iso"\np = "200kPa"\n'
            '[[stage]]\nname = "cyc"\nrepeat = 2\nstop_on_failure = true\n'
            '  [[stage.stages]]\n  name = "up"\n  preset = "undrained"\n  q = "0.5 * p0"\n  steps = 40\n'
            '  [[stage.stages]]\n  name = "down"\n  preset = "undrained"\n  q = "-0.5 * p0"\n  steps = 40\n')
    f = tmp_path / "p.toml"
    f.write_text(text)
    prog = Program.from_toml(f)
    ps = along_program(prog, prog.with_params([]), every=5, n_probes=24)
    assert len(ps.check_step) >= 160 // 5
    if math.isfinite(ps.controllability_step):
        assert ps.bifurcation_step <= ps.controllability_step
    assert main(["stability", "--program", str(f), "--probes", "24", "--out", str(tmp_path / "o")]) == 0
    summary = (tmp_path / "o" / "summary.csv").read_text().splitlines()
    assert summary[0] == "quantity,axial_strain,step,found_by" and len(summary) == 3
    assert main(["stability", "--program", str(f), "--at", "0.01", "--out", str(tmp_path / "x")]) == 1
    assert "hmodel: error:" in capsys.readouterr().err and not (tmp_path / "x").exists()


def test_flow_under_q_control_is_a_loss_of_controllability_found_after_the_entry():
    """Loose, undrained q cycles beyond the extension strength: the q target of an increment
    cannot be carried (flow). That unsolvable increment is the loss of controllability under
    the program's control; probes find the domain at or before its last converged state."""
    prog = Program.from_dict({"params": {"n_theta": 36, "alpha0": 60}, "stage": [
        {"preset": "iso", "p": "200kPa"},
        {"name": "cyc", "repeat": 3, "stop_on_failure": True, "stages": [
            {"name": "up", "preset": "undrained", "q": "0.7 * p0", "steps": 50},
            {"name": "down", "preset": "undrained", "q": "-0.7 * p0", "steps": 50}]}]})
    ps = along_program(prog, prog.with_params([]), n_probes=36)
    assert ps.result.meta["stopped"] and "failure" in ps.result.meta["stopped"][0]
    assert ps.controllability_by == "unsolvable increment"
    assert ps.controllability_step == ps.result["step"][-1]
    assert ps.bifurcation_step <= ps.controllability_step
