"""``load(path)``: read any supported scan or segmentation into a :class:`Volume` (or a
:class:`~anatomesh.core.model.segmentation.Segmentation` of layers when structures overlap).

Dispatch by what the path is: a folder or list of NIfTI/NRRD files → binary masks, one structure
per file (:mod:`.masks`); a folder or a list of files → DICOM (an image series, or the DICOM SEG /
RTSTRUCT found there: :mod:`.dicom_seg`, :mod:`.rtstruct`); ``.nii``/``.nii.gz`` → NIfTI;
``.nrrd``/``.nhdr`` (including 3D Slicer's ``.seg.nrrd``) → NRRD; a single ``.dcm`` (or a file
starting with the DICOM preamble) → that object alone: a SEG or RTSTRUCT itself (its referenced
image series looked up in its folder when the grid needs it), else the slices of its image series
found in its folder; damaged or unrelated files beside it are skipped, never an error.

Whatever pydicom, highdicom, nibabel or pynrrd print about a file while it is read becomes a
one-line note in ``.warnings`` (:mod:`.library_messages`).

What comes back: a label-map or scan :class:`Volume` when every structure fits one label map;
a :class:`Segmentation` (``.layers``: label-map Volumes on one grid, ``.overlaps`` in mm³) when
structures overlap (a lumen inside the aorta, overlapping SEG segments, nested RT ROIs).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional, Sequence, Union

from ..model.errors import AnatomeshError
from ..model.progress import Progress
from ..model.segmentation import Segmentation
from ..model.volume import Volume
from .library_messages import notes_of_library

PathLike = Union[str, os.PathLike]

NIFTI_SUFFIXES = (".nii", ".nii.gz")
NRRD_SUFFIXES = (".nrrd", ".nhdr")


@notes_of_library
def load(path: Union[PathLike, Sequence[PathLike]], *, series: Optional[str] = None,
         volume_index: Optional[int] = None, labels: Optional[PathLike] = None,
         label_map: Optional[bool] = None, space: Optional[str] = None,
         grid: Optional[str] = None, progress: Optional[Progress] = None) -> Union[Volume, Segmentation]:
    """Read a scan or label map.

    Parameters
    ----------
    path : path or list of paths
        A DICOM folder (searched recursively), a list of DICOM files, a ``.nii``/``.nii.gz``,
        ``.nrrd``/``.nhdr`` or ``.seg.nrrd`` file.
    series : str, optional
        DICOM only, when a folder holds several series or segmentation objects: tried as the
        1-based index in the listed order (image series first, then SEG/RTSTRUCT objects, as
        ``anatomesh inspect`` and the error message list them), then as SeriesNumber, then as
        SeriesInstanceUID (or a segmentation's SOPInstanceUID). A folder holding an image series
        and one segmentation object reads the segmentation unless ``series`` picks the image.
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
    grid : str, optional
        Mask folders, DICOM SEG and RTSTRUCT: the grid structures are meshed on. Masks: a
        structure name or ``"image"`` (default the finest mask grid); SEG/RTSTRUCT: ``"image"``
        (the referenced series, the default when present) or ``"native"`` (built from the
        object's own planes).
    progress : callable, optional
        ``progress(fraction, text)``.

    Raises
    ------
    AnatomeshError
        With a one-line message naming the file and the problem.
    """
    from .masks import mask_files, read_masks
    if isinstance(path, (list, tuple)):
        if not path:
            raise AnatomeshError("no files given (empty list); give a file, a folder or a list of files")
        files = mask_files(path)
        if files:
            vol = read_masks(files, grid=grid, space=space, progress=progress)
        else:
            from .dicom_objects import read_dicom_any
            vol = read_dicom_any([Path(p) for p in path], series=series, grid=grid,
                                 progress=progress)
    else:
        p = Path(path)
        if not p.exists():
            raise AnatomeshError("no such file or folder; check the path", p)
        name = p.name.lower()
        if p.is_dir() and mask_files(p):
            vol = read_masks(mask_files(p), grid=grid, space=space, progress=progress)
        elif p.is_dir():
            from .dicom_objects import read_dicom_any
            vol = read_dicom_any(p, series=series, grid=grid, progress=progress)
        elif name.endswith(NIFTI_SUFFIXES):
            from .nifti import read_nifti
            vol = read_nifti(p, volume_index=volume_index, labels=labels, label_map=label_map)
        elif name.endswith(NRRD_SUFFIXES):
            from .nrrd import read_nrrd
            vol = read_nrrd(p, labels=labels, label_map=label_map)
        elif name.endswith(".dcm") or _has_dicom_preamble(p):
            from .dicom_objects import read_dicom_any
            vol = read_dicom_any(p, series=series, grid=grid, progress=progress)  # that object, or that file's series
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
