"""Readers: every supported scan format → :class:`~anatomesh.core.model.volume.Volume`; mask folders,
DICOM SEG and RTSTRUCT with overlapping structures → :class:`~anatomesh.core.model.segmentation.Segmentation`."""
from .load import load

__all__ = ["load"]
