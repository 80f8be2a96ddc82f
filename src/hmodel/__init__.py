"""hmodel: the micromechanical H-model of granular materials (Nicot & Darve 2011)."""

from .kernel_cache import configure as _configure_kernel_cache

_configure_kernel_cache()  # before any kernel is defined (hmodel.kernel_cache says why)

from .errors import HModelError, InputError, SolverError
from .params import Params

__version__ = "0.1.0"
__all__ = ["Params", "HModelError", "InputError", "SolverError", "__version__"]
