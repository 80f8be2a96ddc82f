"""A progress bar that appears only when the work lasts longer than a second."""

from __future__ import annotations

import sys
import time

from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn


class LazyProgress:
    """Callable receiving the completed fraction (0..1); draws a Rich bar after ``delay`` s.

    Use as a context manager so the bar is closed whatever happens.
    """

    def __init__(self, description: str, delay: float = 1.0, enabled: bool | None = None):
        self.description = description
        self.delay = delay
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._start = time.perf_counter()
        self._bar: Progress | None = None
        self._task = None

    def __call__(self, fraction: float) -> None:
        if not self.enabled:
            return
        if self._bar is None:
            if time.perf_counter() - self._start < self.delay:
                return
            self._bar = Progress(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                                 TimeElapsedColumn(), transient=True)
            self._bar.start()
            self._task = self._bar.add_task(self.description, total=1.0)
        self._bar.update(self._task, completed=min(max(fraction, 0.0), 1.0))

    def __enter__(self) -> "LazyProgress":
        self._start = time.perf_counter()
        return self

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.stop()
