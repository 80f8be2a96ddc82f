"""A calibrated model run again: what ``calibration.json`` records of the fitted model (its
parameters, variant, reference void ratio, directions and cell solver), read back so that a
test of another density and pressure runs with it (``--calibration DIR``)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..params import Params
from ..rev import Sphere
from ..variants import ModelVariant, get_variant


@dataclass(frozen=True)
class CalibratedModel:
    """The fitted model of a calibration folder.

    Attributes: ``params`` (the fitted and fixed parameters, bit for bit as fitted),
    ``variant``, ``e_ref`` (the void ratio at which ``params.alpha0`` holds, for a variant that
    uses e0), ``dim`` (2 or 3), ``sphere`` (3D: the directions it was fitted with), ``solver``
    (the cell solver's spec), ``source`` (the JSON file).
    """

    params: Params
    variant: ModelVariant
    e_ref: float | None
    dim: int
    sphere: Sphere | None
    solver: str
    source: Path

    @classmethod
    def load(cls, folder: "str | Path") -> CalibratedModel:
        """The model of ``folder/calibration.json`` (or of that file itself); a one-line
        InputError when it is missing, not JSON, or written by a version without the record."""
        path = Path(folder)
        path = path / "calibration.json" if path.is_dir() else path
        try:
            record = json.loads(path.read_text())
        except OSError as e:
            raise InputError(f"cannot read calibration {str(path)!r}: {e.strerror}") from None
        except (UnicodeDecodeError, ValueError):
            raise InputError(f"calibration {str(path)!r} is not a calibration.json file") from None
        model = record.get("model") if isinstance(record, dict) else None
        if not isinstance(model, dict) or "params_rad" not in model:
            raise InputError(f"calibration {str(path)!r} records no model to run (calibrate again with this "
                             f"version of hmodel)")
        try:
            params = Params(**model["params_rad"])
            sphere = Sphere(**{**record["sphere"], "axis": tuple(record["sphere"]["axis"])}) \
                if record.get("sphere") else None
            return cls(params, get_variant(model["variant"]), model.get("e_ref"), int(model["dim"]), sphere,
                       str(model.get("solver", "closed-form")), path)
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"calibration {str(path)!r}: malformed model record ({e})") from None

    def params_at(self, e0: float | None = None) -> Params:
        """The parameters of a specimen at void ratio ``e0`` (None: as fitted)."""
        if e0 is not None and not self.variant.uses_e0:
            raise InputError(f"--e0 sets the initial state through a model that uses it (sand); this calibration's "
                             f"model is {self.variant.name}")
        if e0 is not None and not (math.isfinite(e0) and e0 > 0):
            raise InputError(f"--e0 must be a positive void ratio, got {e0:g}")
        return self.variant.initial_params(self.params, self.dim, e0, self.e_ref)

    def describe(self) -> str:
        """One line: where the model comes from and what it is."""
        ref = f" at e_ref = {self.e_ref:.4g}" if self.e_ref is not None else ""
        return f"calibrated model {self.variant.name}{ref} ({self.dim}D) from {self.source}"
