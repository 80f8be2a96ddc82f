"""The OpenSees driver of the KFS benchmark's peer (benchmarks/calibration/manzari_dafalias.py):
its drained triaxial test starts elastic with the stiffness of Dafalias & Manzari's elasticity at
the consolidation's p0 and e0, and a long test ends at the critical state of the material's own
parameters. Skipped where openseespy is not installed (an optional benchmark dependency)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("openseespy.opensees")

from benchmarks.calibration.manzari_dafalias import MDParams, drained_triaxial  # noqa: E402

# KFS-like: Mc from a critical friction angle of 33.1°, the critical state line of the benchmark's
# loose tests; the others Dafalias & Manzari's (2004) Toyoura sand.
SAND = MDParams(Mc=1.335, c=0.692, e_c0=1.044, lambda_c=0.0667, ksi=0.296)


@pytest.mark.parametrize("p0", [5e4, 1e5, 4e5])
def test_starts_elastic_with_the_models_stiffness(p0):
    """Within the yield surface (m = 0.05: q up to 0.05 p), a drained test's first slopes are
    elastic: dq/dεa = 9KG/(3K + G) and dεv/dεa = (dq/dεa)/(3K), K and G at p0 and the void
    ratio the material was built with (OpenSees evaluates (2.97 − e)²/(1 + e) at e_init, before
    consolidation, not at the current e: 4 % apart at 400 kPa), while the test starts from
    the test's e0 (the consolidation's strain accounted for)."""
    sand = SAND.with_(m=0.05)
    strains = np.array([0.0, 1e-6, 2e-6, 5e-6])
    c = drained_triaxial(sand, p0, 0.8, strains, step=1e-6, record=1e-6)
    assert c.completed
    assert c.e_start == pytest.approx(0.8, abs=1e-5)
    assert c.e_init > c.e_start  # the consolidation compressed it
    k, g = sand.moduli(p0, c.e_init)
    young = 9 * k * g / (3 * k + g)
    assert c.q[1] / strains[1] == pytest.approx(young, rel=1e-3)
    assert c.eps_v[1] / strains[1] == pytest.approx(young / (3 * k), rel=1e-3)
    # still elastic at 5·10⁻⁶: the slope only follows √p (p rises by q/3)
    assert c.q[3] / strains[3] == pytest.approx(young, rel=2e-3)


def test_a_long_test_ends_at_the_critical_state():
    """A loose specimen sheared to 40 % ends on the critical state line of its parameters:
    q/p at Mc and e at e_c(p) = e_c0 − λc (p/p_atm)^ξ."""
    strains = np.linspace(0.0, 0.4, 41)
    c = drained_triaxial(SAND, 1e5, 0.95, strains, step=1e-4)
    assert c.completed and c.reached == pytest.approx(0.4)
    assert c.q[-1] / c.p_end == pytest.approx(SAND.Mc, abs=0.02)
    assert c.e_end == pytest.approx(float(SAND.e_critical(c.p_end)), abs=5e-3)
    # drained with σr held at p0: p = p0 + q/3
    assert c.p_end == pytest.approx(1e5 + c.q[-1] / 3, rel=1e-3)
    # the material's void ratio, from its total strain: e_start − (1 + e_init) εv
    assert c.e_start == pytest.approx(0.95, abs=1e-5)
    assert c.e_end == pytest.approx(c.e_start - (1 + c.e_init) * c.eps_v[-1], abs=1e-5)
