"""Progress reporting without knowing who listens.

Long functions take ``progress: Progress | None``: a callable ``progress(fraction, text)`` with
``fraction`` in [0, 1]. A caller cancels by raising :class:`~anatomesh.core.model.errors.Cancelled`
from inside the callback. The CLI passes a terminal bar, Blender its progress cursor.
"""
from __future__ import annotations

from typing import Callable, Optional

Progress = Callable[[float, str], None]


def report(progress: Optional[Progress], fraction: float, text: str = "") -> None:
    """Call ``progress`` if there is one; clamps ``fraction`` to [0, 1]."""
    if progress is not None:
        progress(min(1.0, max(0.0, float(fraction))), text)


def sub(progress: Optional[Progress], start: float, stop: float) -> Optional[Progress]:
    """A callback mapping [0, 1] onto [start, stop] of ``progress`` (for nested steps)."""
    if progress is None:
        return None

    def _inner(fraction: float, text: str = "") -> None:
        progress(start + (stop - start) * min(1.0, max(0.0, fraction)), text)

    return _inner
