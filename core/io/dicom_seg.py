"""DICOM Segmentation (SEG) objects → label-map layers on the referenced image grid.

Frames are decoded by highdicom (Herrmann et al. 2022, "Highdicom: a Python library for
standardized encoding of image annotations and machine learning model outputs in pathology and
radiology"): 1-bit BINARY frames (also when frames do not start on a byte boundary), FRACTIONAL
frames (PROBABILITY or OCCUPANCY) and the Label Map Segmentation SOP class (1.2.840.10008.5.1.4.1.1.66.7,
pixel value = segment number), in any transfer syntax pydicom/pylibjpeg decode (JPEG 2000 ...).

* Fractional segments: a voxel is inside when its value is at least 0.5 of the
  MaximumFractionalValue (a note says so).
* Geometry comes from each frame's own Plane Position (Patient) and the shared or per-frame
  Plane Orientation and Pixel Measures, never from SliceThickness. Each frame is placed on the grid
  by its position: the referenced series' grid when it is present (the surfaces land on the CT
  voxel for voxel; every frame must fall on one of its voxels), else a grid built from the frame
  positions (step: the smallest distance between planes along the normal; empty planes between them
  stay empty).
* Each segment keeps its number as label value, its SegmentLabel as name, its recommended colour
  (CIELab → sRGB, :class:`highdicom.color.CIELabColor`) or else the anatomical palette's, and its
  codes (category, type, algorithm) in ``meta["segments"]``.
* Overlapping segments become layers (:mod:`anatomesh.core.model.segmentation`); empty segments are
  skipped with a warning.
"""
from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.labels import LabelInfo, label_table_for
from ..model.progress import Progress, report
from ..model.segmentation import crop_mask, segmentation_from_masks
from .dicom_values import floats, int_or, short_error, text_of

#: fraction of MaximumFractionalValue from which a fractional voxel counts as inside
FRACTION_THRESHOLD = 0.5
#: how far (in voxels) a frame may sit from a grid voxel and still be placed on it
ON_GRID_TOLERANCE = 0.02


def read_seg(path: Path, ref, use_image: bool, progress: Optional[Progress] = None):
    """Read the SEG at ``path`` onto the referenced grid (``ref``, when ``use_image``) or its own.

    Returns a label-map Volume (LPS) or a Segmentation (overlapping segments); ``meta``:
    ``format`` "dicom-seg", ``segmentation_type``, ``segments`` (number, label, codes, colour),
    ``grid`` (what the grid was built from), ``notes``.
    """
    import highdicom as hd
    import pydicom

    try:
        ds = pydicom.dcmread(path)
        seg = hd.seg.Segmentation.from_dataset(ds, copy=False)
        report(progress, 0.1, "decoding SEG frames")
        frames = np.asarray(seg.get_stored_frames())
    except Exception as err:  # damaged file, missing codec: pydicom/highdicom raise many kinds
        raise AnatomeshError(f"cannot decode this DICOM SEG ({short_error(err)}); check the file and "
                             "that pylibjpeg-openjpeg is installed for JPEG 2000", path) from None
    if frames.ndim == 2:
        frames = frames[None]
    kind = text_of(ds, "SegmentationType").upper()
    positions, row, col, spacing, thickness, numbers = frame_geometry(ds, path)
    notes = []
    if kind == "FRACTIONAL":
        top = float(int_or(ds.get("MaximumFractionalValue"), 255))
        frames = frames >= FRACTION_THRESHOLD * top
        notes.append(f"fractional SEG ({text_of(ds, 'SegmentationFractionalType') or 'PROBABILITY'}): "
                     f"voxels at or above {FRACTION_THRESHOLD:g} of the maximum fractional value "
                     f"({top:g}) are inside")
    if use_image:
        affine, shape = ref.affine, ref.shape
        grid = f"the referenced image series (…{ref.series_uid[-12:]}), {'x'.join(map(str, shape))} voxels"
    else:
        affine, shape = native_grid(positions, row, col, spacing, thickness, frames.shape[1:])
        grid = (f"the SEG's own frame positions ({len(np.unique(np.round(positions @ np.cross(row, col), 3)))} "
                f"planes), {'x'.join(map(str, shape))} voxels")
    index = frame_indices(positions, affine, shape, frames.shape[1:], path)
    report(progress, 0.5, "placing segments")
    segments, infos, warnings = _segments(ds, seg, kind)
    masks = []
    for number, info in infos.items():
        full = np.zeros(shape, bool)
        sel = np.flatnonzero(numbers == number) if numbers is not None else np.arange(len(frames))
        for f in sel:
            i, j, k = index[f]
            plane = frames[f] == number if kind == "LABELMAP" else frames[f] != 0
            full[i:i + plane.shape[1], j:j + plane.shape[0], k] |= plane.T
        m = crop_mask(info, full)
        if m is None:
            warnings.append(f"segment {number} ({info.name!r}) is empty: skipped")
        else:
            masks.append(m)
    meta = {"format": "dicom-seg", "modality": "SEG", "source": str(path), "segmentation_type": kind,
            "segments": segments, "grid": grid, "notes": notes, "series_uid": text_of(ds, "SeriesInstanceUID"),
            "frame_of_reference_uid": text_of(ds, "FrameOfReferenceUID")}
    report(progress, 1.0, "SEG read")
    return segmentation_from_masks(masks, shape, affine, "LPS", meta, warnings)


def frame_geometry(ds, path) -> Tuple[np.ndarray, np.ndarray, np.ndarray, Tuple[float, float],
                                       Optional[float], Optional[np.ndarray]]:
    """Per frame: positions (F, 3) LPS mm; the row and column unit vectors; pixel spacing
    (dx along a row, dy down a column) mm; slice thickness (or None); the segment number of each
    frame (F,) int, None for a label-map SEG."""
    shared = ds.get("SharedFunctionalGroupsSequence", [None])[0]
    per = ds.get("PerFrameFunctionalGroupsSequence", [])
    if not per:
        raise AnatomeshError("the SEG has no per-frame functional groups: frame positions unknown", path)

    def item(group, name):
        for g in (group, shared):
            if g is not None and name in g and len(g[name].value):
                return g[name][0]
        raise AnatomeshError(f"the SEG lacks {name}; its frames cannot be placed in space", path)

    iop = np.array(floats(item(per[0], "PlaneOrientationSequence"), "ImageOrientationPatient", 6, path))
    pm = item(per[0], "PixelMeasuresSequence")
    ps = floats(pm, "PixelSpacing", 2, path)
    thick = pm.get("SliceThickness")
    positions = np.array([floats(item(g, "PlanePositionSequence"), "ImagePositionPatient", 3, path)
                          for g in per])
    numbers = None
    if "SegmentIdentificationSequence" in per[0] or (shared is not None and "SegmentIdentificationSequence" in shared):
        numbers = np.array([int(item(g, "SegmentIdentificationSequence").ReferencedSegmentNumber) for g in per])
    if text_of(ds, "SegmentationType").upper() == "LABELMAP":
        numbers = None
    row, col = iop[:3] / np.linalg.norm(iop[:3]), iop[3:] / np.linalg.norm(iop[3:])
    return positions, row, col, (float(ps[1]), float(ps[0])), (float(thick) if thick else None), numbers


def native_grid(positions, row, col, spacing, thickness, frame_shape) -> Tuple[np.ndarray, Tuple[int, int, int]]:
    """A grid through every frame plane: in-plane axes and spacing of the frames, slice step the
    smallest distance between distinct planes along the normal (one plane: the slice thickness,
    else the in-plane spacing), covering every frame."""
    normal = np.cross(row, col)
    t = positions @ normal
    planes = np.unique(np.round(t, 4))
    steps = np.diff(planes)
    step = float(steps[steps > 1e-3].min()) if np.any(steps > 1e-3) else float(thickness or min(spacing))
    u = (positions - positions[0]) @ np.stack([row, col]).T
    lo = np.array([u[:, 0].min() / spacing[0], u[:, 1].min() / spacing[1]])
    origin = positions[0] + row * lo[0] * spacing[0] + col * lo[1] * spacing[1] + normal * (planes[0] - t[0])
    affine = np.eye(4)
    affine[:3, 0], affine[:3, 1], affine[:3, 2], affine[:3, 3] = row * spacing[0], col * spacing[1], normal * step, origin
    span = (u.max(axis=0) - u.min(axis=0)) / np.asarray(spacing)
    shape = (int(round(span[0])) + frame_shape[1], int(round(span[1])) + frame_shape[0],
             int(round((planes[-1] - planes[0]) / step)) + 1)
    return affine, shape


def frame_indices(positions, affine, shape, frame_shape, path) -> np.ndarray:
    """Grid index (i, j, k) of each frame's first pixel; raises when a frame is off the grid."""
    idx = (np.linalg.inv(affine) @ np.c_[positions, np.ones(len(positions))].T)[:3].T
    near = np.round(idx)
    off = np.abs(idx - near).max(axis=1)
    rows, cols = frame_shape
    if np.any(off > ON_GRID_TOLERANCE):
        f = int(np.argmax(off))
        raise AnatomeshError(f"frame {f + 1} lies {off[f]:.2f} voxels off the grid of the referenced series; "
                             "mesh it on its own geometry with --grid native", path)
    near = near.astype(np.int64)
    bad = (near < 0).any(axis=1) | (near[:, 0] + cols > shape[0]) | (near[:, 1] + rows > shape[1]) | \
        (near[:, 2] >= shape[2])
    if np.any(bad):
        f = int(np.flatnonzero(bad)[0])
        raise AnatomeshError(f"frame {f + 1} reaches outside the referenced series' grid; mesh it on its "
                             "own geometry with --grid native", path)
    return near


def _segments(ds, seg, kind: str) -> Tuple[List[Dict], Dict[int, LabelInfo], List[str]]:
    """Segment descriptions (codes for meta) and label entries (value = segment number)."""
    from highdicom.color import CIELabColor

    facts, names, colours = [], {}, {}
    for item in ds.get("SegmentSequence", []):
        n = int(item.SegmentNumber)
        label = text_of(item, "SegmentLabel") or f"segment {n}"
        if kind == "LABELMAP" and (n == 0 or label.lower() == "background"):
            continue
        entry = {"number": n, "label": label, "algorithm": text_of(item, "SegmentAlgorithmType")}
        for key, seq in (("category", "SegmentedPropertyCategoryCodeSequence"),
                         ("type", "SegmentedPropertyTypeCodeSequence")):
            if seq in item and len(item[seq].value):
                c = item[seq][0]
                entry[key] = {"code": text_of(c, "CodeValue"), "scheme": text_of(c, "CodingSchemeDesignator"),
                              "meaning": text_of(c, "CodeMeaning")}
        if "RecommendedDisplayCIELabValue" in item:
            rgb = CIELabColor.from_dicom_value(list(item.RecommendedDisplayCIELabValue)).to_rgb(clip=True)
            colours[n] = tuple(round(c / 255.0, 4) for c in rgb)
            entry["color"] = list(colours[n])
        names[n] = label
        facts.append(entry)
    table = label_table_for(names, names)
    for n, rgb in colours.items():
        table[n] = LabelInfo(n, names[n], rgb)
    return facts, table, []
