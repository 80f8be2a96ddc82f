"""Surrogate formulations: what a network sees and learns, and the way back to the cell's state.

- :mod:`.base`: the base class :class:`Formulation`, which declares everything the training
  code and the cell solver read of a formulation, with an H-cell formulation's defaults.
- :mod:`.strain`: ``report``, ``increment`` and ``report-leak``, networks that see the strain
  increment with the state.
- :mod:`.compliance`: ``compliance``, a network of the state's compliances, the contact law
  applied exactly.
- :mod:`.meso`: ``meso``, any cell (richer DEM cells too) through a summary state
  (:mod:`.meso_summary`), a response head (:mod:`.meso_head`) and rollout training
  (:mod:`.meso_rollout`).
- :mod:`.registry`: the formulations by name, made for a material or rebuilt from a model file.
"""

from .base import OUTPUTS, Formulation
from .registry import FORMULATIONS, formulation_from_dict, make_formulation

__all__ = ["FORMULATIONS", "OUTPUTS", "Formulation", "formulation_from_dict", "make_formulation"]
