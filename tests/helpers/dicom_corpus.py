"""Small DICOM series for tests, made from real head-CT slices (copied, then edited with pydicom).

The source is the Slicer "CTHeadAxial" series (``shared/data/slicer_ctheadaxial``): 93 slices of
64x64 pixels, 3.2 mm pixels, ``CTHead<n>.dcm`` at z = 1.5 (n - 1) mm, identity orientation.
"""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Callable, List, Optional

import pydicom
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.uid import ExplicitVRLittleEndian, generate_uid

HEAD_CT = "slicer_ctheadaxial"


def head_slices(shared, dest: Path, first: int = 40, n: int = 6,
                skip: tuple = ()) -> List[Path]:
    """Copy ``CTHead<first>.dcm`` … ``CTHead<first+n-1>.dcm`` (minus ``skip``) into ``dest``.

    Returns the copies in slice-position order (z ascending).
    """
    dest.mkdir(parents=True, exist_ok=True)
    out = []
    for num in range(first, first + n):
        if num in skip:
            continue
        name = f"CTHead{num}.dcm"
        out.append(Path(shutil.copy(shared(HEAD_CT, name), dest / name)))
    return out


def edit(paths, change: Callable[[Dataset, int], None]) -> None:
    """Apply ``change(dataset, index)`` to each file and save it in place."""
    for index, path in enumerate(paths):
        ds = pydicom.dcmread(path)
        change(ds, index)
        ds.save_as(path)


def non_image_object(path: Path, sop_class: str, modality: str = "",
                     series_uid: Optional[str] = None) -> Path:
    """Write a minimal DICOM object without pixels (e.g. a DICOMDIR, an SR or an RTSTRUCT)."""
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop_class
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID = sop_class
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    if modality:
        ds.Modality = modality
    ds.SeriesInstanceUID = series_uid or generate_uid()
    ds.save_as(path, enforce_file_format=True)
    return path
