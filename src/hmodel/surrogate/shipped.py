"""The surrogates shipped inside the package, so that the ANN-based H-model works after install.

- ``default`` (``h-cell-default.safetensors``): formulation ``compliance``, trained on single
  REV-scale increments (:data:`REV_DATASET`); the one ``--solver surrogate`` uses.
- ``increment`` (``h-cell-increment.safetensors``): formulation ``increment``, trained on the
  report-scale Dataset 2 (1 % increments in 10 sub-steps); the surrogate of report ch. 2.
- ``hexagon-center`` (``hexagon-center-{0,1}.safetensors``): two networks of formulation
  ``meso``, a richer cell with no closed form (the hexagon with a free centre grain) learned from
  YADE's DEM increments, stepped in cell strains of at most 2.5e-4 (``cell_step``); their
  increments average, their disagreement is the trust score of ``--gate`` (stored with the
  first). Runs without YADE, with ``sliding_rhs=equilibrium``; gated, with
  ``--fallback dem:hexagon-center``.
- ``ensemble`` (``h-cell-ensemble-{0,1,2}.safetensors``): the default network and two more of
  its recipe (seeds 1, 2), whose compliances average and whose disagreement is the trust score
  of ``--gate`` (stored with the first, a copy of the default network).

- ``family`` (``h-cell-family.safetensors``): the default network's recipe over a range of
  materials (kt/kn 0.2–1, φg 10–45°, α0 35–75°; kn and r scaled out): kt/kn and tan φg are
  inputs, the training domain is stored and checked.
- ``hexagon-center-family`` (``hexagon-center-family.safetensors``): the richer cell's ``meso``
  network over a range of materials (kt/kn 0.2–1, φg 10–45°, α0 35–60°: kt/kn, tan φg and α0
  are inputs), from 508,800 DEM rows of 168 materials; runs without YADE, with
  ``sliding_rhs=equilibrium``, and calibrates.

Each is produced by the commands in ``models/README.md`` (a fixed dataset, sample and seed) and
loaded like any other model file (checked, never unpickled).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..data import DatasetSpec
from ..errors import InputError
from .training import TrainConfig

SHIPPED = {"default": "h-cell-default.safetensors", "increment": "h-cell-increment.safetensors",
           "hexagon-center-0": "hexagon-center-0.safetensors", "hexagon-center-1": "hexagon-center-1.safetensors",
           "ensemble-0": "h-cell-ensemble-0.safetensors", "ensemble-1": "h-cell-ensemble-1.safetensors",
           "ensemble-2": "h-cell-ensemble-2.safetensors",
           "equilibrium": "h-cell-equilibrium.safetensors", "family": "h-cell-family.safetensors",
           "hexagon-center-family": "hexagon-center-family.safetensors"}
#: Shipped ensembles by name: their members, the one holding the ensemble's trust first.
ENSEMBLES = {"ensemble": ("ensemble-0", "ensemble-1", "ensemble-2"),
             "hexagon-center": ("hexagon-center-0", "hexagon-center-1")}

#: The database of the default model: Dataset 2 increments of at most 0.2 % (the size of a
#: REV's cell increments), each one step of eq. 1.7, from paths in every direction between
#: −60° and 150° of the (ε1, ε2) plane, so that start states include cells in extension and open
#: cells, as in a REV under shear.
REV_DATASET = DatasetSpec(kind=2, n_directions=71, theta_min=-60.0, theta_max=150.0,
                          alpha0_min=32.0, alpha0_max=88.0, alpha0_step=4.0, max_strain=0.2,
                          step=0.001, start_every=0.002, magnitude=0.002, magnitude_min=0.0,
                          n_increments=24, substeps=1)


#: The default model's training (``hmodel surrogate train --formulation compliance --width 64
#: --depth 3 --activation silu --epochs 614 --patience 60``), on 600k random rows of REV_DATASET.
DEFAULT_TRAINING = TrainConfig(formulation="compliance", width=64, depth=3, activation="silu",
                               epochs=614, patience=60, seed=0)


def shipped_path(name: str = "default") -> Path:
    if name not in SHIPPED:
        raise InputError(f"no shipped surrogate named {name!r} (shipped: {', '.join(SHIPPED)})")
    path = Path(str(resources.files("hmodel.surrogate") / "models" / SHIPPED[name]))
    if not path.is_file():
        raise InputError(f"the shipped surrogate {SHIPPED[name]} is missing from this installation")
    return path


def model_path(ref: str) -> Path:
    """A model reference: a shipped model's name (``default``, ``increment``; ``shipped`` is the
    default) or a model file's path (a shipped ensemble's name: :func:`model_paths`)."""
    if not ref.strip():
        raise InputError("a model reference is empty: give shipped, a shipped model's name or a "
                         "model file (A+B+... for an ensemble)")
    if ref == "shipped":
        return shipped_path()
    return shipped_path(ref) if ref in SHIPPED else Path(ref)


def model_paths(spec: str) -> list[Path]:
    """The model files of ``A+B+...``: each a model reference (:func:`model_path`) or a shipped
    ensemble's name (``ensemble``: its members, in order)."""
    refs = [r for part in spec.split("+") for r in ENSEMBLES.get(part, (part,))]
    return [model_path(r) for r in refs]


def load_shipped(name: str = "default"):
    from .modelfile import load
    return load(shipped_path(name))
