"""Loading paths at the material point: control, paths, recipes, result tables (report §1.1.2)."""

from .comparison_paths import PathSpec, run_recipe, standard_paths
from .control import Control, Tangent, solve_increment
from .lab_tests import (
    run_biaxial,
    run_isotropic,
    run_oedometer,
    run_strain_path,
    run_triaxial,
    run_true_triaxial,
)
from .named_paths import (
    AXIAL_STEP,
    ISO_STEP,
    MAX_STRAIN_STEP,
    biaxial,
    consolidate,
    constant_p,
    oedometric,
    proportional,
    strain_path,
)
from .newton import NewtonSettings
from .program import Program, ProgramFailed
from .result import COLUMNS, PathResult, Recorder
from .segment import Segment, SegmentOutcome, StageFailed, run_segment

__all__ = ["Control", "Tangent", "NewtonSettings", "solve_increment", "Segment", "run_segment", "consolidate",
           "biaxial", "oedometric", "constant_p", "proportional", "strain_path", "PathResult",
           "Recorder", "COLUMNS", "run_biaxial", "run_isotropic", "run_strain_path",
           "run_triaxial", "run_true_triaxial", "run_oedometer",
           "ISO_STEP", "AXIAL_STEP", "MAX_STRAIN_STEP", "PathSpec", "standard_paths", "run_recipe",
           "Program", "ProgramFailed", "SegmentOutcome", "StageFailed"]
