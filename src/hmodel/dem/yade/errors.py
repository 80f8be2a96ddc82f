"""The failures of a DEM run: every one is a :class:`DEMError` with a one-line message."""

from __future__ import annotations

from ...errors import SolverError


class DEMError(SolverError):
    """A DEM run failed: YADE missing, crashed, timed out or did not reach equilibrium."""


class YadeNotFound(DEMError):
    """No YADE executable."""


class EquilibriumError(DEMError):
    """The quasi-static criterion was not met within the iteration cap."""
