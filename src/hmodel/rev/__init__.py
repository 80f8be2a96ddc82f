"""The REV: directions, localization, averaging (eqs. 1.1, 1.13-1.21), in 2D and in 3D."""

from .directions import Directions
from .rev import Rev, RevState
from .rev3d import Rev3D
from .sphere import Sphere

__all__ = ["Directions", "Rev", "Rev3D", "RevState", "Sphere"]
