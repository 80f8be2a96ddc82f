"""A persistent YADE process answering one-increment requests (:mod:`hmodel.dem.yade_server`).

Starting YADE costs far more than answering a request of a few dozen cells, so each DEM cell
solver keeps one process, started on first use and ended with the solver or at exit. A
process that dies, answers nothing within the timeout or reports a failure gives a
:class:`~hmodel.dem.yade.DEMError` with a one-line message (the process is then restarted on
the next request). After ``fork`` (multiprocessing workers) the child starts its own.
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

from .yade import DEMError, EquilibriumError, _last_line, find_yade

SCRIPT = Path(__file__).with_name("yade_server.py")
COMMON = Path(__file__).with_name("yade_common.py")
MARK = "@@HMODEL-DEM@@ "


class YadeServer:
    """One YADE process; :meth:`request` sends a JSON object and returns the answer."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen | None = None
        self.exe = ""
        self._pid = 0
        self._tmp: str | None = None
        self._buf = b""
        self.calls = 0
        self.wall_s = 0.0

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
        (Path(self._tmp) / "server.py").write_text(SCRIPT.read_text())
        (Path(self._tmp) / COMMON.name).write_text(COMMON.read_text())
        err = open(Path(self._tmp) / "stderr.txt", "w")
        env = dict(os.environ, OMP_NUM_THREADS="1")
        try:
            self._proc = subprocess.Popen([exe, "-n", "-j1", "-x", "server.py"], cwd=self._tmp,
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err,
                                          env=env)
        except OSError as e:
            self.close()
            raise DEMError(f"YADE could not be started ({exe}): {e.strerror}") from None
        finally:
            err.close()
        self._pid = os.getpid()
        self._buf = b""
        self._read(timeout)  # the "ready" line

    def _read(self, timeout: float) -> dict:
        """The next answer line (YADE's own output is skipped)."""
        proc = self._proc
        fd = proc.stdout.fileno()
        deadline = time.monotonic() + timeout
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while True:
                while b"\n" in self._buf:
                    line, self._buf = self._buf.split(b"\n", 1)
                    text = line.decode(errors="replace")
                    if text.startswith(MARK):
                        return json.loads(text[len(MARK):])
                left = deadline - time.monotonic()
                if left <= 0 or not sel.select(left):
                    self.close()
                    raise DEMError(f"YADE timed out after {timeout:g} s")
                chunk = os.read(fd, 1 << 20)
                if not chunk:
                    code = proc.wait()
                    tail = self._stderr_tail()
                    self.close()
                    raise DEMError(f"YADE crashed (exit status {code}): {tail}")
                self._buf += chunk

    def request(self, payload: dict, timeout: float = 600.0) -> dict:
        """Send one request; raise DEMError / EquilibriumError on failure."""
        t0 = time.perf_counter()
        if not self._alive():
            self._proc = None
            self._start(timeout)
        try:
            self._proc.stdin.write((json.dumps(payload) + "\n").encode())
            self._proc.stdin.flush()
        except (BrokenPipeError, OSError):
            code = self._proc.wait()
            tail = self._stderr_tail()
            self.close()
            raise DEMError(f"YADE crashed (exit status {code}): {tail}") from None
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
