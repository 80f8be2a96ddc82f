"""The script YADE executes (``yade -n -j1 -x serve.py MARK``, YADE side, see
:mod:`hmodel.dem.yade.scripts`): one JSON request per line on stdin, one answer per line on
stdout prefixed by ``MARK`` (YADE's own output is skipped by the client); an empty line or EOF
ends it. It first answers ``{"status": "ready"}``.

A request names its ``task``: ``runs`` (:mod:`~hmodel.dem.yade.scripts.cell_runs`),
``increment`` (:mod:`~hmodel.dem.yade.scripts.cell_increment`), ``biaxial``
(:mod:`~hmodel.dem.yade.scripts.biaxial`) or ``triaxial`` (:mod:`~hmodel.dem.yade.scripts.triaxial`). An answer has ``status`` (``"ok"``,
``"no-equilibrium"`` or ``"error"``), ``message`` and ``wall_s``, the request's time in YADE [s];
an exception is answered as an ``error`` with its first line, and the process goes on.
"""

import json
import os
import sys
import time

try:  # pytest collecting the package's doctests
    from . import biaxial, bihex_cells, cell_increment, cell_runs, triaxial
except ImportError:  # in YADE: the scripts lie side by side in the working directory
    sys.path.insert(0, os.getcwd())
    import biaxial
    import bihex_cells
    import cell_increment
    import cell_runs
    import triaxial


def answer(request):
    """The answer to one request (a dict), never an exception."""
    tasks = {"runs": cell_runs.run, "increment": cell_increment.run, "biaxial": biaxial.run,
             "triaxial": triaxial.run, "bihex": bihex_cells.run}
    task = request.get("task")
    if task not in tasks:
        return {"status": "error", "message": f"unknown task {task!r} (known: {', '.join(tasks)})"}
    try:
        return tasks[task](request)
    except Exception as e:  # answered, not fatal: the client raises a one-line error
        return {"status": "error", "message": f"{type(e).__name__}: {e}".splitlines()[0]}


def main(mark):
    write = sys.__stdout__.write
    write(mark + json.dumps({"status": "ready"}) + "\n")
    sys.__stdout__.flush()
    for line in sys.stdin:
        line = line.strip()
        if not line:
            break
        t0 = time.time()
        res = answer(json.loads(line))
        res["wall_s"] = time.time() - t0
        write(mark + json.dumps(res) + "\n")
        sys.__stdout__.flush()


if __name__ == "__main__":
    main(sys.argv[1])
