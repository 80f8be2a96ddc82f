"""Exceptions of hmodel. The CLI prints their message as one line and exits non-zero."""


class HModelError(Exception):
    """Base class of every error hmodel raises on purpose."""


class InputError(HModelError, ValueError):
    """Bad user input: a parameter, an option, a file."""


class SolverError(HModelError, RuntimeError):
    """A loading step could not be solved (singular cell system, diverging Newton, NaN)."""
