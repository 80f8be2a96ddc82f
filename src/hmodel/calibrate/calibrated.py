"""A calibrated model run again: what ``calibration.json`` records of the fitted model (its
parameters, variant, reference void ratio, directions and cell solver), read back so that a
test of another density and pressure runs with it (``--calibration DIR``)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
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
    (the cell solver's spec), ``source`` (the JSON file), ``radial`` (3D: how its drained
    triaxial tests held their sides, :func:`~hmodel.loading.run_triaxial`).
    """

    params: Params
    variant: ModelVariant
    e_ref: float | None
    dim: int
    sphere: Sphere | None
    solver: str
    source: Path
    radial: str = "free"

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
                       str(model.get("solver", "closed-form")), path, str(model.get("radial", "free")))
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


@dataclass(frozen=True)
class Specimen:
    """What --model, --calibration, --e0 and --e-ref say of a run's material: the parameters it
    starts from (a calibration's, or the defaults), its variant, and each point's void ratio."""

    base: Params | None
    variant: ModelVariant
    e_ref: float | None
    e0: tuple[float, ...]
    dim: int
    sphere: Sphere | None = None
    #: how a calibration's drained triaxial tests held their sides (None without one: by the
    #: parameters)
    radial: str | None = None

    @classmethod
    def make(cls, model: str | None, calibration: "str | Path | None", e0: Sequence[float] | None,
             e_ref: float | None, dim: int) -> "Specimen | None":
        """From a variant's name, a calibration folder, void ratios and a reference void ratio
        (the run commands' --model, --calibration, --e0, --e-ref); None when none is given."""
        if model is None and calibration is None and e0 is None and e_ref is None:
            return None
        cal = CalibratedModel.load(calibration) if calibration is not None else None
        variant = get_variant(model) if model is not None else (cal.variant if cal else get_variant(None))
        if cal is not None:
            if cal.dim != dim:
                raise InputError(f"--calibration {calibration} is of the {cal.dim}D model, this test of the {dim}D one")
            if variant.name != cal.variant.name:
                raise InputError(f"--model {model}: the calibration's model is {cal.variant.name}")
        e0s = tuple(float(e) for e in e0) if e0 is not None else ()
        for e in e0s:
            if not (math.isfinite(e) and e > 0):
                raise InputError(f"--e0 must be positive void ratios, got {e:g}")
        if e0s and not variant.uses_e0:
            raise InputError(f"--e0 sets the initial state through a model that uses it (--model sand); "
                             f"the model here is {variant.name}")
        e_ref = e_ref if e_ref is not None else (cal.e_ref if cal is not None else None)
        if e0s and e_ref is None:
            raise InputError("--e0 needs the void ratio at which alpha0 holds: --e-ref, or a --calibration")
        return cls(cal.params if cal else None, variant, e_ref, e0s, dim, cal.sphere if cal else None,
                   cal.radial if cal else None)

    def at_e0(self, sets: list[Params], n_pressures: int) -> list[Params]:
        """Each point's parameters at its void ratio (broadcast: equal lengths, or one)."""
        if not self.e0:
            return [self.variant.apply(s) for s in sets]
        n = max(len(sets), len(self.e0), n_pressures)
        for what, k in (("--param lists", len(sets)), ("--e0", len(self.e0)), ("--p0", n_pressures)):
            if k not in (1, n):
                raise InputError(f"{what} gives {k} material points and another option {n}: give equal lengths, or one value")
        return [self.variant.initial_params(sets[i if len(sets) > 1 else 0], self.dim,
                                            self.e0[i if len(self.e0) > 1 else 0], self.e_ref) for i in range(n)]
