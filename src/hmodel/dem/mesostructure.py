"""The cell descriptions of the DEM cells, which live in the cell layer since the surrogates of
richer cells need their geometry without YADE: :mod:`hmodel.cell.mesostructure`. Re-exported
here for the ``hmodel dem`` commands and the DEM pages of the documentation."""

from ..cell.mesostructure import (CONSTRUCTORS, DRIVES, HEX_DRIVE, TYPE1, TYPE1_SIGN, TYPE2, Mesostructure,
                                  build, hexagon_center, hexagon_unequal, standard)

__all__ = ["CONSTRUCTORS", "DRIVES", "HEX_DRIVE", "TYPE1", "TYPE1_SIGN", "TYPE2", "Mesostructure", "build",
           "hexagon_center", "hexagon_unequal", "standard"]
