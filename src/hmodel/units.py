"""Parsing of physical quantities given on the command line."""

from __future__ import annotations

import math
import re

from .errors import InputError

_PRESSURE_UNITS = {"": 1.0, "pa": 1.0, "kpa": 1e3, "mpa": 1e6, "gpa": 1e9}
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_pressure(text: str) -> float:
    """A pressure in Pa from ``200kPa``, ``0.2MPa``, ``2e5`` or ``2e5Pa``.

    >>> parse_pressure("200kPa"), parse_pressure("0.2 MPa"), parse_pressure("150000")
    (200000.0, 200000.0, 150000.0)
    """
    m = re.fullmatch(rf"\s*({_NUMBER})\s*([A-Za-z]*)\s*", str(text))
    if not m or m.group(2).lower() not in _PRESSURE_UNITS:
        raise InputError(f"cannot read pressure {text!r} (examples: 200kPa, 0.2MPa, 200000)")
    value = float(m.group(1)) * _PRESSURE_UNITS[m.group(2).lower()]
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"pressure must be positive and finite, got {text!r}")
    return value


def parse_pressures(text: str) -> list[float]:
    """Comma-separated pressures: ``100kPa,200kPa,400kPa`` -> [1e5, 2e5, 4e5]."""
    parts = [p for p in str(text).split(",")]
    if not parts or any(not p.strip() for p in parts):
        raise InputError(f"cannot read pressure list {text!r} (example: 100kPa,200kPa,400kPa)")
    return [parse_pressure(p) for p in parts]
