"""DEM cells solved by YADE (optional: needs the ``yade`` executable, never imported by hmodel's core).

- :mod:`~hmodel.dem.solver`: the DEM cell solver, on the cell descriptions and state layout of
  :mod:`hmodel.cell.mesostructure` and :mod:`hmodel.cell.geometry`;
- :mod:`~hmodel.dem.scene`: many cells in one YADE scene, driven by (dl1, dl2) increments, and
  the scene settings the solver shares;
- :mod:`~hmodel.dem.yade`: YADE behind one door, the scripts YADE runs and the client that
  runs them (one process answering JSON requests), its errors;
- :mod:`~hmodel.dem.validate`: the DEM standard cell against the closed form (eq. 1.7);
- :mod:`~hmodel.dem.bihex`: the bi-hexagon of the 3D model as a DEM cell of ten spheres, the
  cell solver ``dem:bihexagon``; :mod:`~hmodel.dem.validate3d`: it against the closed form;
- :mod:`~hmodel.dem.sample`: a periodic 2D disk sample consolidated and sheared in biaxial
  tests (``hmodel dem sample``: test data to calibrate on).
"""
