"""The registry of surrogate formulations, by name: ``report``, ``increment`` and
``report-leak`` (:mod:`.strain`), ``compliance`` (:mod:`.compliance`) and ``meso``
(:mod:`.meso`), made for a material or rebuilt from a model file's metadata. A new formulation
is a subclass of :class:`~hmodel.surrogate.formulations.base.Formulation` in a module of its own
in this package, listed here.
"""

from __future__ import annotations

from ...errors import InputError
from ...params import Params
from .base import Formulation, is_h_cell
from .compliance import ComplianceFormulation
from .meso import MesoFormulation
from .strain import IncrementFormulation, LeakedReportFormulation, ReportFormulation

FORMULATIONS = ("report", "increment", "compliance", "meso", "report-leak")
#: The strain-input formulations, made from the material's scales.
STRAIN_INPUT = {"report": ReportFormulation, "increment": IncrementFormulation,
                "report-leak": LeakedReportFormulation}


def make_formulation(name: str, params: Params, cell: str = "closed-form", mechanisms: int = 4,
                     cell_step: float | None = None) -> Formulation:
    """The formulation ``name`` for the material of ``params`` and data of the cell solver
    ``cell`` (``mechanisms``, ``cell_step``: the ``meso`` formulation's kinks of its incremental
    response and largest network step, :class:`~hmodel.surrogate.formulations.meso.MesoFormulation`)."""
    if name not in FORMULATIONS:
        raise InputError(f"unknown formulation {name!r} (known: {', '.join(FORMULATIONS)})")
    if name == "meso":
        return MesoFormulation(params, cell, mechanisms, cell_step)
    if cell_step is not None:
        raise InputError("cell_step (--cell-step) is the meso formulation's")
    if not is_h_cell(cell):
        raise InputError(f"the {name} formulation learns H-cells; cells of {cell!r} need --formulation meso")
    if name == "compliance":
        return ComplianceFormulation(params)
    return STRAIN_INPUT[name](params.kn * 2 * params.radius, params.tan_phi, params.radius)


def formulation_from_dict(d: dict) -> Formulation:
    """Inverse of ``to_dict`` (model files)."""
    if d["name"] == "meso":
        return MesoFormulation(Params.from_dict(d["params"]), d["cell"], d["mechanisms"], d.get("cell_step"))
    if d["name"] == "compliance":
        return ComplianceFormulation(Params.from_dict(d["params"]))
    return STRAIN_INPUT[d["name"]](d["force_scale"], d["tan_phi"], d["radius"])
