"""Calibration of the H-model on measured biaxial (2D) or triaxial (3D) tests (the report's
§1.2 perspective).

``fit(tests, fit=..., bounds=..., method="least-squares")`` finds the material parameters whose
tests (drained or undrained biaxial tests of the 2D model; drained, undrained or extension
triaxial tests of the 3D model: :class:`Kind`) reproduce measured curves of q and εv against the
axial strain. Every evaluation runs all the parameter sets it needs (the starts of a design, the
columns of a finite-difference Jacobian) through the engine in one batched call, one material
point per parameter set and test (:func:`hmodel.params.check_batch`). ``check_at`` runs the
tests again at the calibrated parameters with another cell solver (the cell a surrogate learned)
and measures how far the calibrated model lies from it. ``CalibratedModel.load(folder)`` reads
the fitted model back from ``calibration.json`` to run it for another specimen.
"""

from .calibrated import CalibratedModel
from .check import Check, check_at
from .data import Test, parse_data_spec
from .fitting import Calibration, fit
from .kinds import Kind
from .space import DEFAULT_BOUNDS, FITTABLE, Space

__all__ = ["DEFAULT_BOUNDS", "FITTABLE", "CalibratedModel", "Calibration", "Check", "Kind", "Space", "Test", "check_at", "fit", "parse_data_spec"]
