"""Neural surrogates of the H-cell increment (report §2.4-2.5): formulations, normalizations,
PyTorch training, evaluation, safe model files and the shipped model."""

from .formulations import FORMULATIONS, Formulation, make_formulation
from .model import Architecture, Surrogate
from .modelfile import ModelFileError, load, save

__all__ = ["FORMULATIONS", "Architecture", "Formulation", "ModelFileError", "Surrogate", "load",
           "make_formulation", "save"]
