"""A DEM sample to calibrate on: a 2D periodic assembly of polydisperse disks in YADE, consolidated
isotropically to p0 and sheared in a drained or undrained biaxial test; or, with ``dim = 3``, a
3D periodic assembly of polydisperse spheres sheared in a drained or undrained triaxial
compression or a drained triaxial extension (the differences are listed at the end).

- :mod:`~hmodel.dem.sample.geometry`: :class:`Disks` and :class:`Spheres`, everything that
  differs between a 2D and a 3D sample (:func:`grains`);
- :mod:`~hmodel.dem.sample.settings`: :class:`SampleSettings` (everything but a test's kind and
  p0), the strain rate and inertial number;
- :mod:`~hmodel.dem.sample.packing`: the seeded radii and initial gas of disks;
- :mod:`~hmodel.dem.sample.state`: :class:`SampleState` and its measures (porosity,
  coordination, stress);
- :mod:`~hmodel.dem.sample.result`: :class:`SampleTest`, one test's rows, CSV, npz and record;
- :mod:`~hmodel.dem.sample.run`: :func:`run_test` (one test in YADE) and :func:`run_sample`
  (resumable tests into a folder);
- :mod:`~hmodel.dem.sample.draw`: :func:`draw_sample`, the packings and their force chains.

:func:`run_sample` runs one test per pressure and writes, into one folder,

- ``{kind}_{p0}kPa.csv``: ``eps11,q,eps_v,p`` (axial and volumetric logarithmic strain since the
  end of the consolidation, compression positive; q = s11 - s22, p = (s11 + s22) / 2), the
  format of ``hmodel calibrate --data``;
- ``{kind}_{p0}kPa.npz``: every recorded row (also eps22, s11, s22, s12, unbalanced-force ratio,
  contact count) and the consolidated and final states (radii, positions, cell, contacts);
- ``sample.json``: the settings, the YADE version and one record per test (porosity, void
  ratio, coordination numbers, inertial number, servo accuracy, steps, wall times);
- ``sample.png``: the final packing of every test with its contact force chains.

The YADE side is :mod:`hmodel.dem.yade.scripts.biaxial` (read its docstring for the scene and the
servo control).

Units and the 2D convention: lengths in m, forces in N, kn in N/m; stresses are the 2D
Love-Weber stress (1/A) sum f (x) l over the contacts, A the cell's area, in N/m (Pa m: Pa for a
sample of unit thickness), as hmodel's DEM cells
(:meth:`hmodel.cell.geometry.CellGeometry.love_weber`). Masses are those of
disks of unit thickness, ``density`` pi r^2, and the inertial number is
I = strain rate x mean diameter x sqrt(density / p).

Spheres (``dim = 3``, YADE side :mod:`hmodel.dem.yade.scripts.triaxial`): test kinds
``triaxial-drained``, ``triaxial-undrained``, ``triaxial-extension`` (files
``triaxial-drained_100kPa.csv``...); the CSV has :data:`CSV_COLUMNS_3D` (``eps_a, q, eps_v, p``
with q = s11 - (s22 + s33) / 2 and p = tr(s) / 3, the coordination number, the sliding
fraction and the six stress components), stresses are the 3D Love-Weber stress (1/V) sum f (x) l
in Pa, masses density 4/3 pi r^3, and sample.png shows the tests' curves.
"""

from .draw import draw_curves, draw_sample
from .geometry import (CONTACT_COLUMNS, CONTACT_COLUMNS_3D, CSV_COLUMNS, CSV_COLUMNS_3D, DISTRIBUTIONS,
                       DISTRIBUTIONS_3D, KINDS, KINDS_3D, ROW_COLUMNS, ROW_COLUMNS_3D, Disks, Grains,
                       Spheres, grains)
from .packing import initial_packing, mean_diameter, radii
from .result import SampleTest, file_stem
from .run import RESUME_FREE, run_sample, run_test
from .settings import SampleSettings, inertial_number, kinds, option_name, strain_rate
from .state import SampleState

__all__ = ["CONTACT_COLUMNS", "CONTACT_COLUMNS_3D", "CSV_COLUMNS", "CSV_COLUMNS_3D", "DISTRIBUTIONS",
           "DISTRIBUTIONS_3D", "Disks", "Grains", "KINDS", "KINDS_3D", "RESUME_FREE", "ROW_COLUMNS",
           "ROW_COLUMNS_3D", "SampleSettings", "SampleState", "SampleTest", "Spheres", "draw_curves",
           "draw_sample", "file_stem", "grains", "inertial_number", "initial_packing", "kinds",
           "mean_diameter", "option_name", "radii", "run_sample", "run_test", "strain_rate"]
