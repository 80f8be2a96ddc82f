"""A YADE process answering requests, one JSON line each way: the one transport to YADE.

:class:`YadeServer` starts ``yade -n -j1 -x serve.py MARK`` in a temporary folder holding the
YADE-side scripts (:mod:`hmodel.dem.yade.scripts`, copied as text), sends one request per line
on its stdin and reads the answer, the line of its stdout that starts with ``MARK`` (YADE's
own output is skipped). A request names its ``task`` (``runs``, ``increment``, ``biaxial``);
every task rebuilds its scene, so an answer depends on its request only.

The DEM cell solver keeps one server for its many small requests (starting YADE costs far more
than answering a few dozen cells); :func:`run` answers one request in a process of its own
(a validation, a drawing, a biaxial test of a sample). A process that dies, answers nothing
within the timeout or reports a failure gives a :class:`~hmodel.dem.yade.errors.DEMError` with a
one-line message (the process is then restarted on the next request); its folder is removed
whatever happens. After ``fork`` (multiprocessing workers) the child starts its own process.
"""

from __future__ import annotations

import json
import os
import selectors
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from .errors import DEMError, EquilibriumError
from .executable import find_yade

#: The YADE-side scripts, copied side by side into the process's folder.
SCRIPTS = Path(__file__).with_name("scripts")
#: The script YADE executes; the others are imported by it.
ENTRY = "serve.py"
#: Prefix of the answer lines (given to the script on its command line).
MARK = "@@HMODEL-DEM@@ "


def _last_line(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[-1] if lines else "no message"


class YadeServer:
    """One YADE process; :meth:`request` sends a task and returns the answer.

    Parameters
    ----------
    exe : str
        The YADE executable; default :func:`~hmodel.dem.yade.executable.find_yade` at start.

    Attributes
    ----------
    calls : int
        Requests answered.
    wall_s : float
        Wall time of those requests, process starts included [s].
    """

    def __init__(self, exe: str = "") -> None:
        self.exe = exe
        self._proc: subprocess.Popen | None = None
        self._pid = 0
        self._tmp: str | None = None
        self._buf = bytearray()
        self.calls = 0
        self.wall_s = 0.0

    def __enter__(self) -> "YadeServer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def serves(self, exe: str) -> bool:
        """Whether this server can take requests here for ``exe``: not yet started or started by
        this process (not inherited through ``fork``), for that executable."""
        return self._pid in (0, os.getpid()) and self.exe == exe

    @property
    def pid(self) -> int | None:
        """The YADE process's id while it runs for this process, else None."""
        return self._proc.pid if self._alive() else None

    def _alive(self) -> bool:
        return self._proc is not None and self._pid == os.getpid() and self._proc.poll() is None

    def _stderr_tail(self) -> str:
        try:
            return _last_line(Path(self._tmp, "stderr.txt").read_text(errors="replace"))
        except (OSError, TypeError):
            return "no message"

    def _start(self, timeout: float) -> None:
        exe = self.exe or find_yade()
        self._tmp = tempfile.mkdtemp(prefix="hmodel-dem-server-")
        for script in SCRIPTS.glob("*.py"):
            if script.name != "__init__.py":
                (Path(self._tmp) / script.name).write_text(script.read_text())
        err = open(Path(self._tmp) / "stderr.txt", "w")
        env = dict(os.environ, OMP_NUM_THREADS="1")
        try:
            self._proc = subprocess.Popen([exe, "-n", "-j1", "-x", ENTRY, MARK], cwd=self._tmp,
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err,
                                          env=env)
        except OSError as e:
            self.close()
            raise DEMError(f"YADE could not be started ({exe}): {e.strerror}") from None
        finally:
            err.close()
        self._pid = os.getpid()
        self._buf = bytearray()
        self._read(timeout)  # the "ready" line

    def _crashed(self) -> DEMError:
        code = self._proc.wait()
        tail = self._stderr_tail()
        self.close()
        return DEMError(f"YADE crashed (exit status {code}): {tail}")

    def _line(self) -> str | None:
        """The next answer line already read, or None (other complete lines are dropped)."""
        mark = MARK.encode()
        while (end := self._buf.find(b"\n")) >= 0:
            line = bytes(self._buf[:end])
            del self._buf[:end + 1]
            if line.startswith(mark):
                return line[len(mark):].decode(errors="replace")
        return None

    def _read(self, timeout: float) -> dict:
        """The next answer (YADE's own output is skipped)."""
        fd = self._proc.stdout.fileno()
        deadline = time.monotonic() + timeout
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while (line := self._line()) is None:
                # an answer of megabytes arrives in many chunks: the buffer is searched only once
                # a chunk holds a line end, not after every chunk (quadratic in the answer)
                while b"\n" not in (chunk := self._chunk(sel, deadline, timeout)):
                    self._buf += chunk
                self._buf += chunk
        return json.loads(line)

    def _chunk(self, sel: selectors.BaseSelector, deadline: float, timeout: float) -> bytes:
        left = deadline - time.monotonic()
        if left <= 0 or not sel.select(left):
            self.close()
            raise DEMError(f"YADE timed out after {timeout:g} s")
        chunk = os.read(self._proc.stdout.fileno(), 1 << 20)
        if not chunk:
            raise self._crashed()
        return chunk

    def request(self, task: str, payload: dict, timeout: float = 600.0) -> dict:
        """Send ``payload`` as a request of ``task``; return the answer.

        Raises
        ------
        YadeNotFound, DEMError, EquilibriumError
        """
        t0 = time.perf_counter()
        if not self._alive():
            self._proc = None
            self._start(timeout)
        try:
            self._proc.stdin.write((json.dumps({**payload, "task": task}) + "\n").encode())
            self._proc.stdin.flush()
        except (BrokenPipeError, OSError):
            raise self._crashed() from None
        result = self._read(timeout)
        self.calls += 1
        self.wall_s += time.perf_counter() - t0
        if result.get("status") == "no-equilibrium":
            raise EquilibriumError(f"DEM: {result.get('message', 'equilibrium not reached')}")
        if result.get("status") != "ok":
            raise DEMError(f"DEM: {result.get('message') or 'unknown failure'}")
        return result

    def close(self) -> None:
        """End the process (if this process started it) and remove its folder."""
        proc, self._proc = self._proc, None
        if proc is not None and self._pid == os.getpid():
            try:
                if proc.poll() is None:
                    proc.stdin.write(b"\n")
                    proc.stdin.flush()
                    proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired, ValueError):
                proc.kill()
                proc.wait()
            for fh in (proc.stdin, proc.stdout):
                try:
                    fh.close()
                except OSError:
                    pass
        if self._tmp is not None and self._pid in (0, os.getpid()):
            shutil.rmtree(self._tmp, ignore_errors=True)
        self._tmp = None


def run(task: str, payload: dict, timeout: float = 600.0) -> dict:
    """Answer one request of ``task`` in a YADE process of its own, ended once it has answered.

    Raises
    ------
    YadeNotFound, DEMError, EquilibriumError
    """
    with YadeServer(find_yade()) as yade:
        return yade.request(task, payload, timeout)
