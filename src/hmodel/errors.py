"""Exceptions of hmodel. The CLI prints their message as one line and exits non-zero."""

import numpy as np


class HModelError(Exception):
    """Base class of every error hmodel raises on purpose."""


class InputError(HModelError, ValueError):
    """Bad user input: a parameter, an option, a file."""


class SolverError(HModelError, RuntimeError):
    """A loading step could not be solved (singular cell system, diverging Newton, NaN)."""


class PointFailure(SolverError):
    """A loading step that some material points of a batch could not take.

    ``points`` are their indices in the batch that raised it; a caller that ran a sub-batch
    ``index`` of a larger one names them in its own batch with :meth:`renumber`, and a caller
    running many independent points (a calibration) drops them and goes on with the others.
    """

    def __init__(self, message: str, points) -> None:
        super().__init__(message)
        self.points = np.asarray(points, np.int64)

    def renumber(self, index) -> "PointFailure":
        """The failure with its points named by ``index`` (the sub-batch's indices in the
        caller's batch); the same exception, so its traceback is kept."""
        self.points = index[self.points]
        return self

    def drop_into(self, failures: dict) -> np.ndarray:
        """Record its points as dropped in ``failures`` (point -> the one-line reason), for a
        caller that goes on with the other points; returns the points."""
        for b in self.points:
            failures[int(b)] = " ".join(str(self).split())
        return self.points

