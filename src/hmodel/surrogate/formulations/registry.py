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


#: The material inputs of a family network of each formulation (rows that draw a material per
#: path): an H-cell's compliance depends on its state, kt/kn and tan φg; a ``meso`` summary also
#: on α0, which sets the richer cell's geometry (the centre grain's touching radius).
FAMILY_INPUTS = {"compliance": ("kt_kn", "tan_phi_g"), "meso": ("kt_kn", "tan_phi_g", "alpha0")}


def make_formulation(name: str, params: Params, cell: str = "closed-form", mechanisms: int = 4,
                     cell_step: float | None = None, family: bool = False) -> Formulation:
    """The formulation ``name`` for the material of ``params`` and data of the cell solver
    ``cell`` (``mechanisms``, ``cell_step``: the ``meso`` formulation's kinks of its incremental
    response and largest network step, :class:`~hmodel.surrogate.formulations.meso.MesoFormulation`);
    with ``family``, a network over a range of materials (:data:`FAMILY_INPUTS`)."""
    if name not in FORMULATIONS:
        raise InputError(f"unknown formulation {name!r} (known: {', '.join(FORMULATIONS)})")
    if family and name not in FAMILY_INPUTS:
        raise InputError(f"a network over a range of materials (rows with a material per path) is "
                         f"of formulation {' or '.join(FAMILY_INPUTS)}, not {name!r}")
    material = FAMILY_INPUTS[name] if family else ()
    if name == "meso":
        return MesoFormulation(params, cell, mechanisms, cell_step, material_inputs=material)
    if cell_step is not None:
        raise InputError("cell_step (--cell-step) is the meso formulation's")
    if not is_h_cell(cell):
        raise InputError(f"the {name} formulation learns H-cells; cells of {cell!r} need --formulation meso")
    if name == "compliance":
        return ComplianceFormulation(params, material)
    return STRAIN_INPUT[name](params.kn * 2 * params.radius, params.tan_phi, params.radius)


def formulation_from_dict(d: dict) -> Formulation:
    """Inverse of ``to_dict`` (model files)."""
    if d["name"] == "meso":
        return MesoFormulation(Params.from_dict(d["params"]), d["cell"], d["mechanisms"], d.get("cell_step"),
                               material_inputs=tuple(d.get("material_inputs", ())))
    if d["name"] == "compliance":
        return ComplianceFormulation(Params.from_dict(d["params"]), tuple(d.get("material_inputs", ())))
    return STRAIN_INPUT[d["name"]](d["force_scale"], d["tan_phi"], d["radius"])
