"""Material stability at the material point: response envelopes and second-order work.

From any state, *probes* apply small increments in many directions to copies of the state, in
one batched call (the state itself is never changed):

- strain probes: dε of magnitude m in N directions (:func:`probe_directions`): in 2D of the
  (ε11, ε22) plane (or, with shear, of (ε11, ε22, √2 ε12) space); in 3D of the principal
  (ε11, ε22, ε33) space (or, with shear, of all six components); the responses dσ draw
  Gudehus' response envelope;
- stress probes (mixed control): dσ of magnitude m·p in N directions of a plane of normal
  stresses (:func:`section_directions`: the (σ11, σ22) plane in 2D, the Rendulic plane
  (σ11, √2 σr), σr = σ22 = σ33, in 3D) with the other components held; the strain responses dε.
  A probe the material cannot sustain (Newton finds no strain increment) has a NaN response:
  controllability is lost in that direction.

Second-order work (Hill): d²W = dσ : dε = Σ dσij dεij (derived here in the REV's Voigt
components: dσ11 dε11 + dσ22 dε22 + 2 dσ12 dε12 in 2D; the three normal products plus twice
each of the three shear products in 3D), normalized by |dσ| |dε| (tensor norms), i.e. the
cosine between the two increments. Directions with d²W ≤ 0 form the instability cone; its
minimum over directions is the scalar indicator; the first state along a path where it is ≤ 0
enters the bifurcation domain. The d²W of the path's own increments changes sign where
controllability is lost under the path's control (the peak of q on an undrained path, the peak
of σ11 on a drained one; on a drained triaxial test σ11 - p0 = q).

Everything here is written for n components: 3 (the 2D REV, (11, 22, 12)) or 6 (the 3D REV,
:class:`hmodel.rev.rev3d.Rev3D`, (11, 22, 33, 23, 13, 12), tensor shear components).

Modules: ``work`` (d²W and tensor norms), ``probes`` (directions and envelopes from one
state), ``locate`` (the bifurcation-domain entry and the loss of controllability on a path),
``analysis`` (probing along a program or a laboratory test), ``study`` (a study as ``hmodel
stability`` runs it, and its report), ``output`` (CSV tables, a study's folder) and
``figures``. Every public name is importable from ``hmodel.stability``.
"""

# (the underscored names: imported by tests and benchmarks from before the package)
from .analysis import DEFAULT_MAGNITUDE, NEAR, along_biaxial, along_program, along_triaxial
from .figures import plot_envelopes, plot_path
from .locate import (RULES, PathStability, _first_persistent, _first_secant_loss, _located,
                     first_sign_change)
from .output import table_writers, write_study
from .probes import (SETTINGS, Envelope, probe_directions, section_directions, strain_envelope,
                     stress_envelope, triaxial_directions)
from .study import TESTS, StabilityStudy, run_study
from .work import loading_work, second_order_work, section, shear_factors, tensor_norm

__all__ = ["DEFAULT_MAGNITUDE", "NEAR", "RULES", "SETTINGS", "TESTS", "Envelope", "PathStability",
           "StabilityStudy", "along_biaxial", "along_program", "along_triaxial", "first_sign_change",
           "loading_work", "plot_envelopes", "plot_path", "probe_directions", "run_study",
           "second_order_work", "section", "section_directions", "shear_factors",
           "strain_envelope", "stress_envelope", "table_writers", "tensor_norm",
           "triaxial_directions", "write_study"]
