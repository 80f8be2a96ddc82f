"""Parsing of physical quantities given on the command line."""

from __future__ import annotations

import math
import re

import numpy as np

from .errors import InputError

_PRESSURE_UNITS = {"": 1.0, "pa": 1.0, "kpa": 1e3, "mpa": 1e6, "gpa": 1e9}
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


#: A pressure typed without unit below this [Pa] is refused (:func:`parse_pressure` with an
#: ``option``): a geomechanics user writing 100 means kPa, and 100 Pa is no consolidation
#: pressure of a laboratory test or a boundary-value problem.
BARE_PRESSURE_MIN = 1e4


def parse_pressure(text: str, option: str | None = None) -> float:
    """A pressure in Pa from ``200kPa``, ``0.2MPa``, ``2e5`` or ``2e5Pa``.

    ``option``: where a user typed it (``--p0``, a test's ``p0``): a bare number (no unit) is
    then Pa and refused below :data:`BARE_PRESSURE_MIN`, naming the unit to add; with a unit
    (``100Pa`` included) any positive pressure is taken.

    >>> parse_pressure("200kPa"), parse_pressure("0.2 MPa"), parse_pressure("150000")
    (200000.0, 200000.0, 150000.0)
    >>> parse_pressure("100", "--p0")
    Traceback (most recent call last):
    ...
    hmodel.errors.InputError: --p0 100 has no unit and would be 100 Pa: give its unit (100kPa, or 100Pa if Pa is meant)
    """
    m = re.fullmatch(rf"\s*({_NUMBER})\s*([A-Za-z]*)\s*", str(text))
    if not m or m.group(2).lower() not in _PRESSURE_UNITS:
        raise InputError(f"cannot read pressure {text!r} (examples: 200kPa, 0.2MPa, 200000)")
    value = float(m.group(1)) * _PRESSURE_UNITS[m.group(2).lower()]
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"pressure must be positive and finite, got {text!r}")
    if option is not None and not m.group(2) and value < BARE_PRESSURE_MIN:
        bare = m.group(1)
        raise InputError(f"{option} {bare} has no unit and would be {value:g} Pa: give its unit "
                         f"({bare}kPa, or {bare}Pa if Pa is meant)")
    return value


def parse_pressures(text: str, option: str | None = None) -> list[float]:
    """Comma-separated pressures: ``100kPa,200kPa,400kPa`` -> [1e5, 2e5, 4e5]; ``option``: as
    :func:`parse_pressure`, for each."""
    parts = [p for p in str(text).split(",")]
    if not parts or any(not p.strip() for p in parts):
        raise InputError(f"cannot read pressure list {text!r} (example: 100kPa,200kPa,400kPa)")
    return [parse_pressure(p, option) for p in parts]


#: Units a column header may carry, as factors to hmodel's (a strain fraction, Pa).
STRAIN_UNITS = {"%": 1e-2, "-": 1.0, "1": 1.0, "": 1.0}
STRESS_UNITS = {"pa": 1.0, "kpa": 1e3, "mpa": 1e6, "": 1.0}
STRAIN_COLUMNS = ("eps11", "eps_a", "eps_v", "eps_r")
STRESS_COLUMNS = ("q", "p", "sigma_r", "sigma_v", "sig11", "sig22", "sig33")
_HEADER = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\[\s*([^\]]*?)\s*\])?\s*$")


def unit_factor(header: str) -> tuple[str, float]:
    """A column header ``name[unit]`` as its name and the factor to hmodel's unit: strains
    (``eps_*``) in ``%`` or ``-``, stresses (``q``, ``p``, ``sigma_*``, ``sig*``) in ``Pa``,
    ``kPa`` or ``MPa``; a header without unit is in hmodel's units already. Other columns keep
    factor 1 whatever their unit.

    >>> unit_factor("eps_a[%]"), unit_factor("q[kPa]"), unit_factor("q")
    (('eps_a', 0.01), ('q', 1000.0), ('q', 1.0))
    """
    m = _HEADER.match(header)
    if not m:
        raise InputError(f"cannot read column header {header!r} (expected NAME or NAME[UNIT], e.g. eps_a[%])")
    name, unit = m.group(1), (m.group(2) or "")
    if name in STRAIN_COLUMNS:
        if unit not in STRAIN_UNITS:
            raise InputError(f"column {header!r}: a strain's unit must be % or - (a fraction), got {unit!r}")
        return name, STRAIN_UNITS[unit]
    if name in STRESS_COLUMNS:
        if unit.lower() not in STRESS_UNITS:
            raise InputError(f"column {header!r}: a stress's unit must be Pa, kPa or MPa, got {unit!r}")
        return name, STRESS_UNITS[unit.lower()]
    return name, 1.0


def has_units(header: list[str]) -> bool:
    """Whether any column header of ``header`` carries a unit in brackets."""
    return any("[" in h for h in header)


def convert_columns(header: list[str], data: np.ndarray, where: str) -> dict[str, np.ndarray]:
    """Columns by name in hmodel's units from a table whose headers may carry units; ``q`` is
    derived as σv − σr when the table gives ``sigma_v`` and ``sigma_r`` and no ``q``."""
    cols: dict[str, np.ndarray] = {}
    for i, h in enumerate(header):
        name, factor = unit_factor(h)
        if name in cols:
            raise InputError(f"{where}: column {name} given twice")
        cols[name] = data[:, i] * factor
    if "q" not in cols and "sigma_v" in cols and "sigma_r" in cols:
        cols["q"] = cols["sigma_v"] - cols["sigma_r"]
    return cols
