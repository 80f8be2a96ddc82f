"""The REV: directions, localization, averaging (eqs. 1.1, 1.13-1.21)."""

from .directions import Directions
from .rev import Rev, RevState

__all__ = ["Directions", "Rev", "RevState"]
