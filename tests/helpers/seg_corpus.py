"""Small DICOM SEGs for reader tests, made with highdicom from real head-CT slices (copied from
``shared/data/slicer_ctheadaxial``: 64x64 pixels of 3.2 mm, slices 1.5 mm apart and 1.5 mm thick;
given a FrameOfReferenceUID, which the SEG IOD requires and these files lack),
and edits of a SEG's frame geometry with pydicom (frame positions moved, Pixel Measures changed).
"""
from __future__ import annotations

import warnings
from pathlib import Path
from typing import Callable, Dict, List, Sequence

import numpy as np
import pydicom
from pydicom.uid import generate_uid

from helpers.dicom_corpus import edit, head_slices


def head_ct(shared, folder: Path, first: int = 40, n: int = 6) -> List[Path]:
    """Copy ``n`` head-CT slices into ``folder`` (z ascending), with a patient name and character
    set highdicom accepts without a warning."""
    files = head_slices(shared, folder, first=first, n=n)
    frame_of_reference = generate_uid()
    edit(files, lambda ds, _: (setattr(ds, "PatientName", "Head^Phantom"),
                               setattr(ds, "SpecificCharacterSet", "ISO_IR 100"),
                               setattr(ds, "FrameOfReferenceUID", frame_of_reference)))
    return files


def binary_seg(ct_files: Sequence[Path], labels: np.ndarray, path: Path,
               names: Sequence[str] = ("bone", "brain"), omit_empty: bool = True) -> Path:
    """Write a BINARY SEG of ``labels`` (uint8 (slices, rows, cols), value n = segment n) on the
    CT slices ``ct_files`` (z ascending); empty frames are left out when ``omit_empty`` (as
    highdicom does by default). Returns ``path``."""
    import highdicom as hd
    from pydicom.sr.codedict import codes

    source = [pydicom.dcmread(f) for f in ct_files]
    descs = [hd.seg.SegmentDescription(
        segment_number=n, segment_label=name, segmented_property_category=codes.SCT.Tissue,
        segmented_property_type=codes.SCT.Organ, algorithm_type=hd.seg.SegmentAlgorithmTypeValues.MANUAL)
        for n, name in enumerate(names, 1)]
    seg = hd.seg.Segmentation(
        source_images=source, pixel_array=labels, segmentation_type=hd.seg.SegmentationTypeValues.BINARY,
        segment_descriptions=descs, series_instance_uid=hd.UID(), series_number=99,
        sop_instance_uid=hd.UID(), instance_number=1, manufacturer="test", manufacturer_model_name="test",
        software_versions="1", device_serial_number="1", omit_empty_frames=omit_empty)
    seg.save_as(path)
    return path


def edit_seg(path: Path, change: Callable[[pydicom.Dataset], None], out: Path = None) -> Path:
    """Apply ``change`` to the SEG data set and save it (in place, or to ``out``)."""
    ds = pydicom.dcmread(path)
    change(ds)
    target = out or path
    ds.save_as(target)
    return target


def frame_positions(ds) -> np.ndarray:
    """(F, 3) ImagePositionPatient of every frame, mm."""
    return np.array([[float(v) for v in g.PlanePositionSequence[0].ImagePositionPatient]
                     for g in ds.PerFrameFunctionalGroupsSequence])


def move_frames(offsets_mm: np.ndarray) -> Callable[[pydicom.Dataset], None]:
    """An edit that adds ``offsets_mm`` (F, 3) to the frames' positions (written with 6 decimals)."""
    def change(ds):
        for g, d in zip(ds.PerFrameFunctionalGroupsSequence, offsets_mm):
            p = np.array([float(v) for v in g.PlanePositionSequence[0].ImagePositionPatient]) + d
            g.PlanePositionSequence[0].ImagePositionPatient = [f"{x:.6f}" for x in p]
    return change


def pixel_measures(**values) -> Callable[[pydicom.Dataset], None]:
    """An edit that sets (value) or removes (None) Pixel Measures attributes in the shared groups."""
    def change(ds):
        pm = ds.SharedFunctionalGroupsSequence[0].PixelMeasuresSequence[0]
        for key, value in values.items():
            if value is None:
                if key in pm:
                    delattr(pm, key)
            else:
                setattr(pm, key, value)
    return change


def segment_voxels(ds) -> Dict[str, int]:
    """{segment label: pixels inside} counted over a SEG's frames with pydicom alone: BINARY
    frames != 0, FRACTIONAL frames >= half the maximum fractional value, label-map frames ==
    the segment number."""
    frames = ds.pixel_array
    frames = frames[None] if frames.ndim == 2 else frames
    kind = str(ds.SegmentationType).upper()
    out = {}
    for item in ds.SegmentSequence:
        n = int(item.SegmentNumber)
        if kind == "LABELMAP":
            if n == 0 or str(item.SegmentLabel).lower() == "background":
                continue
            out[str(item.SegmentLabel)] = int(np.count_nonzero(frames == n))
            continue
        sel = [f for f, g in enumerate(ds.PerFrameFunctionalGroupsSequence)
               if int(_segment_of(ds, g)) == n]
        mine = frames[sel]
        if kind == "FRACTIONAL":
            inside = mine >= 0.5 * float(ds.MaximumFractionalValue)
        else:
            inside = mine != 0
        out[str(item.SegmentLabel)] = int(np.count_nonzero(inside))
    return out


def _segment_of(ds, group) -> int:
    for g in (group, ds.SharedFunctionalGroupsSequence[0]):
        if "SegmentIdentificationSequence" in g:
            return int(g.SegmentIdentificationSequence[0].ReferencedSegmentNumber)
    raise KeyError("SegmentIdentificationSequence")


def quiet(call, *args, **kwargs):
    """``call(*args, **kwargs)`` with the libraries' own warnings silenced (building test data)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return call(*args, **kwargs)
