"""YADE behind one door: the scripts YADE runs and the client that runs them.

hmodel never imports YADE. The YADE-side scripts (:mod:`hmodel.dem.yade.scripts`, never
imported by hmodel: they are copied as text next to each other and executed by YADE's own
Python) answer requests of three tasks, each on a scene built from the request alone:

- ``runs``: many cells, each under its own list of increments (:func:`hmodel.dem.scene.simulate`);
- ``increment``: one increment of many cells given by their states (the DEM cell solver,
  :mod:`hmodel.dem.solver`);
- ``biaxial``: a periodic disk sample consolidated and sheared (:mod:`hmodel.dem.sample`).

The client (:mod:`~hmodel.dem.yade.server`) is the one transport: a YADE process reading one
JSON request per line and answering one line. :func:`run` answers one request in a process of
its own; a :class:`YadeServer` keeps its process for many. Every failure is a
:class:`DEMError` with a one-line message (:mod:`~hmodel.dem.yade.errors`).
"""

from .errors import DEMError, EquilibriumError, YadeNotFound
from .executable import INSTALL_HINT, available, find_yade
from .server import YadeServer, run

__all__ = ["DEMError", "EquilibriumError", "INSTALL_HINT", "YadeNotFound", "YadeServer", "available",
           "find_yade", "run"]
