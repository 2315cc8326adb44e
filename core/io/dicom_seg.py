"""DICOM Segmentation (SEG) objects → label-map layers on the referenced image grid.

Frames are decoded by highdicom (Herrmann et al. 2022, "Highdicom: a Python library for
standardized encoding of image annotations and machine learning model outputs in pathology and
radiology"): 1-bit BINARY frames (also when frames do not start on a byte boundary), FRACTIONAL
frames (PROBABILITY or OCCUPANCY) and the Label Map Segmentation SOP class (1.2.840.10008.5.1.4.1.1.66.7,
pixel value = segment number), in any transfer syntax pydicom/pylibjpeg decode (JPEG 2000 ...).

* Fractional segments: a voxel is inside when its value is at least 0.5 of the
  MaximumFractionalValue (a note says so).
* Geometry comes from each frame's own Plane Position (Patient) and the Plane Orientation and
  Pixel Measures, exactly as the file gives them (:mod:`.seg_grid`). Frames are placed on the
  referenced series' grid when it is present and shares the frames' pixel lattice (the surfaces
  land on the CT voxel for voxel), else on the SEG's own grid; in both, a frame must lie within
  :data:`~.seg_grid.ON_GRID_TOLERANCE` of a voxel. Planes without a frame are empty planes.
* Each segment keeps its number as label value, its SegmentLabel as name, its recommended colour
  (CIELab → sRGB, :class:`highdicom.color.CIELabColor`) or else the anatomical palette's, and its
  codes (category, type, algorithm) in ``meta["segments"]``.
* Overlapping segments become layers (:mod:`anatomesh.core.model.segmentation`); empty segments are
  skipped with a warning.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Dict, List, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.labels import LabelInfo, label_table_for
from ..model.progress import Progress, report
from ..model.segmentation import crop_mask, segmentation_from_masks
from .dicom_pixels import require_decoder
from .dicom_values import int_or, text_of
from .library_messages import notes_of_library, reason
from .seg_grid import FrameGeometry, frame_geometry, native_grid, place_frames, same_in_plane_lattice

#: fraction of MaximumFractionalValue from which a fractional voxel counts as inside
FRACTION_THRESHOLD = 0.5


@notes_of_library
def read_seg(path: Path, ref, use_image: bool, progress: Optional[Progress] = None,
             explicit: bool = False):
    """Read the SEG at ``path`` onto the referenced grid (``ref``, when ``use_image``) or its own.

    ``explicit``: the image grid was asked for (``--grid image``), so a SEG whose pixels differ
    from the series' is an error instead of being meshed on its own grid with a note.

    Returns a label-map Volume (LPS) or a Segmentation (overlapping segments); ``meta``:
    ``format`` "dicom-seg", ``segmentation_type``, ``segments`` (number, label, codes, colour),
    ``grid`` (what the grid was built from), ``notes``.
    """
    ds, seg, frames = _decode(path, progress)
    kind = text_of(ds, "SegmentationType").upper()
    geo = frame_geometry(ds, path, frames.shape[1:])
    if len(geo.positions) != len(frames):
        raise AnatomeshError(f"the SEG has {len(frames)} frames but {len(geo.positions)} frame positions; "
                             "the file is damaged: export the segmentation again", path)
    frames, notes = _inside(frames, ds, kind)
    affine, shape, grid, index, more = _grid(geo, ref, use_image, explicit, path)
    report(progress, 0.5, "placing segments")
    segments, infos, warnings = _segments(ds, seg, kind)
    masks = []
    for number, info in infos.items():
        m = crop_mask(info, _paint(frames, geo, index, number, shape, kind))
        if m is None:
            warnings.append(f"segment {number} ({info.name!r}) is empty: skipped")
        else:
            masks.append(m)
    meta = {"format": "dicom-seg", "modality": "SEG", "source": str(path), "segmentation_type": kind,
            "segments": segments, "grid": grid, "notes": notes + more,
            "series_uid": text_of(ds, "SeriesInstanceUID"),
            "frame_of_reference_uid": text_of(ds, "FrameOfReferenceUID")}
    report(progress, 1.0, "SEG read")
    return segmentation_from_masks(masks, shape, affine, "LPS", meta, warnings)


def _decode(path: Path, progress):
    """(data set, highdicom Segmentation, stored frames (F, rows, cols))."""
    import highdicom as hd
    import pydicom

    try:
        ds = pydicom.dcmread(path)
    except Exception as err:  # pydicom raises many kinds on damaged input
        raise AnatomeshError(f"damaged DICOM SEG, it cannot be read ({reason(err)}); copy it again or "
                             "export the segmentation again", path) from None
    require_decoder(ds, path)
    try:
        seg = hd.seg.Segmentation.from_dataset(ds, copy=False)
        report(progress, 0.1, "decoding SEG frames")
        frames = np.asarray(seg.get_stored_frames())
    except Exception as err:  # damaged file: pydicom/highdicom raise many kinds
        raise AnatomeshError(f"cannot decode the frames of this DICOM SEG ({reason(err)}): the file is "
                             "truncated or damaged; copy it again or export the segmentation again", path) from None
    return ds, seg, frames[None] if frames.ndim == 2 else frames


def _inside(frames: np.ndarray, ds, kind: str) -> Tuple[np.ndarray, List[str]]:
    """Fractional frames thresholded at :data:`FRACTION_THRESHOLD` (with a note); others as stored."""
    if kind != "FRACTIONAL":
        return frames, []
    top = float(int_or(ds.get("MaximumFractionalValue"), 255))
    note = (f"fractional SEG ({text_of(ds, 'SegmentationFractionalType') or 'PROBABILITY'}): voxels at or "
            f"above {FRACTION_THRESHOLD:g} of the maximum fractional value ({top:g}) are inside")
    return frames >= FRACTION_THRESHOLD * top, [note]


def _grid(geo: FrameGeometry, ref, use_image: bool, explicit: bool, path):
    """(affine, shape, description, frame indices (F, 3), notes) of the grid the frames go on."""
    notes: List[str] = []
    if use_image and not same_in_plane_lattice(geo, ref.affine):
        theirs = np.linalg.norm(ref.affine[:3, :2], axis=0)
        what = (f"the SEG's pixels ({geo.spacing[0]:g} x {geo.spacing[1]:g} mm, rows along "
                f"{np.round(geo.row, 4).tolist()}) differ from the referenced series' ({theirs[0]:g} x "
                f"{theirs[1]:g} mm, rows along {np.round(ref.affine[:3, 0] / theirs[0], 4).tolist()})")
        if explicit:
            raise AnatomeshError(f"--grid image cannot be used: {what}; leave --grid out or use --grid "
                                 "native to mesh it on its own grid", path)
        notes.append(f"{what}: meshed on the SEG's own grid")
        use_image = False
    if use_image:
        name = f"the slices of the referenced image series (…{ref.series_uid[-12:]})"
        text = f"the referenced image series (…{ref.series_uid[-12:]}), {'x'.join(map(str, ref.shape))} voxels"
        try:
            index, more = place_frames(geo, ref.affine, ref.shape, path, name)
            return ref.affine, ref.shape, text, index, notes + more
        except AnatomeshError as err:
            if explicit or not ref.incomplete:
                raise AnatomeshError(f"{err.message}; {_image_advice(geo, path)}", path) from None
            notes.append("its frames do not fit the slices found of the referenced series (it is incomplete, "
                         "see above): meshed on the SEG's own grid")
    affine, shape, text, step_notes = native_grid(geo, path)
    advice = ("its frames lie on no common grid of their own; put the image series it was made from beside "
              "it and leave --grid out to mesh it on that series' grid")
    try:
        index, more = place_frames(geo, affine, shape, path, "the SEG's own grid")
    except AnatomeshError as err:
        raise AnatomeshError(f"{err.message}; {advice}", path) from None
    return affine, shape, text, index, notes + step_notes + more


def _image_advice(geo: FrameGeometry, path) -> str:
    """What to do when the frames do not fit the referenced series: --grid native when they fit
    a grid of their own, else re-export."""
    try:
        affine, shape, _, _ = native_grid(geo, path)
        place_frames(geo, affine, shape, path, "")
    except AnatomeshError:
        return ("its frames fit no grid of their own either; export the segmentation again from the "
                "image series")
    return ("the SEG was not made on these slices: mesh it on its own frame positions with --grid native, "
            "or give the image series it was made from")


def _paint(frames: np.ndarray, geo: FrameGeometry, index: np.ndarray, number: int, shape,
           kind: str) -> np.ndarray:
    """bool (I, J, K) voxels of segment ``number``: its frames painted at their grid indices."""
    full = np.zeros(shape, bool)
    sel = np.flatnonzero(geo.numbers == number) if geo.numbers is not None else np.arange(len(frames))
    for f in sel:
        i, j, k = index[f]
        plane = frames[f] == number if kind == "LABELMAP" else frames[f] != 0
        full[i:i + plane.shape[1], j:j + plane.shape[0], k] |= plane.T
    return full


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
        table[n] = dataclasses.replace(table[n], color=rgb, color_given=True)
    return facts, table, []
