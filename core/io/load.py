"""``load(path)``: read any supported scan into a :class:`Volume`.

Dispatch by what the path is: a folder or a list of files → DICOM series; ``.nii``/``.nii.gz``
→ NIfTI; ``.nrrd``/``.nhdr`` (including 3D Slicer's ``.seg.nrrd``) → NRRD; a single ``.dcm`` (or a
file starting with the DICOM preamble) → that file's series, read from its folder.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional, Sequence, Union

from ..model.errors import AnatomeshError
from ..model.progress import Progress
from ..model.volume import Volume

PathLike = Union[str, os.PathLike]

NIFTI_SUFFIXES = (".nii", ".nii.gz")
NRRD_SUFFIXES = (".nrrd", ".nhdr")


def load(path: Union[PathLike, Sequence[PathLike]], *, series: Optional[str] = None,
         volume_index: Optional[int] = None, labels: Optional[PathLike] = None,
         label_map: Optional[bool] = None, space: Optional[str] = None,
         progress: Optional[Progress] = None) -> Volume:
    """Read a scan or label map.

    Parameters
    ----------
    path : path or list of paths
        A DICOM folder (searched recursively), a list of DICOM files, a ``.nii``/``.nii.gz``,
        ``.nrrd``/``.nhdr`` or ``.seg.nrrd`` file.
    series : str, optional
        DICOM only, when a folder holds several series: tried as the 1-based index in the listed
        order (as the error message lists them), then as SeriesNumber, then as SeriesInstanceUID.
    volume_index : int, optional
        NIfTI only: which volume of a 4D image to read.
    labels : path, optional
        A label table (TotalSegmentator JSON, 3D Slicer colour table, ITK-SNAP label file) naming
        the values of a label map; a sidecar next to the file is found automatically.
    label_map : bool, optional
        Force (True) or forbid (False) reading the image as a label map; by default integer images
        with few distinct non-negative values, or with a label table, are label maps.
    space : "RAS" or "LPS", optional
        Express the affine in this space (default: the format's own, DICOM/NRRD LPS, NIfTI RAS).
    progress : callable, optional
        ``progress(fraction, text)``.

    Raises
    ------
    AnatomeshError
        With a one-line message naming the file and the problem.
    """
    if isinstance(path, (list, tuple)):
        if not path:
            raise AnatomeshError("no files given")
        from .dicom import read_dicom
        vol = read_dicom([Path(p) for p in path], series=series, progress=progress)
    else:
        p = Path(path)
        if not p.exists():
            raise AnatomeshError("no such file or folder; check the path", p)
        name = p.name.lower()
        if p.is_dir():
            from .dicom import read_dicom
            vol = read_dicom(p, series=series, progress=progress)
        elif name.endswith(NIFTI_SUFFIXES):
            from .nifti import read_nifti
            vol = read_nifti(p, volume_index=volume_index, labels=labels, label_map=label_map)
        elif name.endswith(NRRD_SUFFIXES):
            from .nrrd import read_nrrd
            vol = read_nrrd(p, labels=labels, label_map=label_map)
        elif name.endswith(".dcm") or _has_dicom_preamble(p):
            from .dicom import read_dicom
            vol = read_dicom(p, series=series, progress=progress)  # reads that file's series
        else:
            raise AnatomeshError(
                "unsupported file type; give a DICOM folder, a .nii/.nii.gz, .nrrd/.nhdr or "
                ".seg.nrrd file", p)
    if space is not None and space != vol.space:
        vol = vol.in_space(space)
    return vol


def _has_dicom_preamble(p: Path) -> bool:
    try:
        with open(p, "rb") as fh:
            head = fh.read(132)
    except OSError:
        return False
    return len(head) == 132 and head[128:132] == b"DICM"
