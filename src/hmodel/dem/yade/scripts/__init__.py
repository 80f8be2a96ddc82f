"""The scripts YADE runs (never imported by hmodel: :mod:`hmodel.dem.yade.server` copies them as
text into one folder and YADE executes ``serve.py`` there).

- ``serve``: the entry point; one JSON request per line on stdin, one answer line on stdout;
- ``cell_scene``: many H-model cells in one scene (material, contact law, detection margin,
  engines, time step, driving, relaxation, contact rows), shared by the two cell tasks;
- ``cell_runs``: task ``runs``, every cell under its own list of increments;
- ``cell_increment``: task ``increment``, one increment of cells given by their states;
- ``biaxial``: task ``biaxial``, a periodic disk sample consolidated and sheared (and the
  servo control the sphere sample shares);
- ``triaxial``: task ``triaxial``, a periodic sphere sample consolidated and sheared;
- ``bihex_cells``: task ``bihex``, bi-hexagons of ten spheres (the 3D model's cell) from their
  states under their increments (material and engines of ``cell_scene``);
- ``common``: what every scene shares (the linear contact stiffnesses, a sample's contact law
  and the stiffness of its time step, stepping).

Each runs in YADE's own Python: standard library only, YADE imported inside the functions that
need it, and the other scripts imported by their plain names from the working directory (by
their package-relative names when pytest collects the package's doctests).
"""
