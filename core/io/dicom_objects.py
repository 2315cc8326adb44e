"""DICOM input of any kind: an image series, a DICOM SEG or an RTSTRUCT (placeholder)."""
from __future__ import annotations

from .dicom import read_dicom


def read_dicom_any(path, series=None, grid=None, progress=None):
    return read_dicom(path, series=series, progress=progress)
