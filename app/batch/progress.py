"""The progress of a batch: one bar (studies done, failed, left, ETA) plus the stage each running
study is at, as a ``progress(fraction, text)`` callback (:mod:`anatomesh.core.model.progress`)."""
from __future__ import annotations

import threading
import time
from typing import Dict, Optional, Tuple

from ...core.model.progress import Progress

#: seconds between two updates of the bar (a finished study always updates it)
INTERVAL = 0.2


class BatchProgress:
    """Counts the studies as they finish and tells ``emit`` as ``emit(fraction, text)``, e.g.
    ``"12 done, 1 failed, 87 left, ETA 4 min | s003: smoothing (organ) · s004: reading"``.

    ``total`` is every study of the batch, ``done``/``failed`` those settled before this run
    (skipped as unchanged, earlier failures). Thread-safe: Dask reports stages from its own
    thread."""

    def __init__(self, total: int, done: int = 0, failed: int = 0, emit: Optional[Progress] = None):
        self.total, self.done, self.failed = total, done, failed
        self.ran = 0
        self.emit = emit
        self.t0 = time.perf_counter()
        self.current: Dict[str, Tuple[float, str]] = {}
        self._lock = threading.Lock()
        self._last = 0.0

    def stage(self, study: str, fraction: float, text: str) -> None:
        with self._lock:
            self.current[study] = (fraction, text)
            self._send(force=False)

    def finished(self, study: str, ok: bool) -> None:
        with self._lock:
            self.current.pop(study, None)
            self.ran += 1
            if ok:
                self.done += 1
            else:
                self.failed += 1
            self._send(force=True)

    @property
    def left(self) -> int:
        return self.total - self.done - self.failed

    def eta(self) -> Optional[float]:
        """Seconds until every study is settled, at this run's pace so far (None before one ends)."""
        if not self.ran:
            return None
        return (time.perf_counter() - self.t0) / self.ran * self.left

    def text(self) -> str:
        eta = self.eta()
        line = (f"{self.done} done, {self.failed} failed, {self.left} left"
                + (f", ETA {duration(eta)}" if eta is not None and self.left else ""))
        stages = [f"{sid}: {text or '...'}" for sid, (_, text) in list(self.current.items())[:4]]
        return line + (" | " + " · ".join(stages) if stages else "")

    def _send(self, force: bool) -> None:
        now = time.perf_counter()
        if self.emit is None or (not force and now - self._last < INTERVAL):
            return
        self._last = now
        settled = self.done + self.failed + sum(f for f, _ in self.current.values())
        self.emit(settled / max(1, self.total), self.text())


def duration(seconds: float) -> str:
    """``42 s``, ``7 min``, ``3.5 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
