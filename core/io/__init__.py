"""Readers: every supported scan format → :class:`~anatomesh.core.model.volume.Volume`."""
from .load import load

__all__ = ["load"]
