"""DICOM RT Structure Sets (RTSTRUCT): closed planar contours per ROI → label-map layers.

Each ROI (``StructureSetROISequence``: number, name; ``ROIContourSequence``: colour, contours) is
read as :class:`~anatomesh.core.model.segmentation.RoiContours` in LPS mm, exactly where the file
puts its points, and checked:

* every contour is ``CLOSED_PLANAR`` with at least 3 points (open contours are an error naming ROI
  and slice); every contour lies in a plane perpendicular to the stack normal (the referenced
  image's, else the mean contour normal: tilted and oblique stacks work) and on one of the stack's
  evenly spaced planes; no contour crosses itself;
* ROIs without contours are skipped with a warning; POINT ROIs (markers) too.

Then every ROI is rasterised by :mod:`.contour_raster` (even-odd rule, shape-based interpolation
between planes) onto a grid built from the referenced CT's in-plane lattice and slice planes when
present, else from the contour planes (plus a lone CT slice's plane when that is all there is).
The contours stay in ``meta["contours"]`` so they can also be tiled directly
(:mod:`anatomesh.core.extract.contours`).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import List, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.labels import label_table_for
from ..model.progress import Progress, report
from ..model.segmentation import RoiContours, segmentation_from_masks
from . import _contour_kernels as K
from .contour_raster import contour_grid, in_plane_axes, rasterise_roi
from .library_messages import notes_of_library, reason
from .dicom_values import text_of

#: a contour point further than this from its plane (mm) makes the contour non-planar
PLANE_TOLERANCE_MM = 0.05
#: a contour whose normal differs from the stack's by more than this (degrees) is off the planes
NORMAL_TOLERANCE_DEG = 1.0


@notes_of_library
def read_rtstruct(path: Path, ref, use_image: bool, progress: Optional[Progress] = None):
    """Read an RTSTRUCT and rasterise its ROIs (see the module docstring).

    Returns a label-map Volume (LPS) or a Segmentation (nested/overlapping ROIs): label value =
    ROINumber, name = ROIName, colour = ROIDisplayColor; ``meta``: ``format`` "dicom-rtstruct",
    ``rois`` (number, name, type, contours, planes), ``contours`` (list of RoiContours), ``grid``.
    """
    import pydicom

    try:
        ds = pydicom.dcmread(path)
    except Exception as err:
        raise AnatomeshError(f"damaged RTSTRUCT, it cannot be read ({reason(err)}); copy it again or "
                             "export the structure set again", path) from None
    normal = None
    if ref is not None and ref.plane is not None:
        normal = np.cross(ref.plane["row"], ref.plane["col"])
    rois, warnings = read_rois(ds, path, normal)
    if not rois:
        raise AnatomeshError("no ROI of this RTSTRUCT has a closed contour, so there is nothing to mesh; "
                             "export the structure set with its contours", path)
    report(progress, 0.2, "rasterising contours")
    grid = contour_grid(rois, ref, use_image, path)
    masks = []
    for n, roi in enumerate(rois):
        m = rasterise_roi(roi, grid)
        if m is None:
            warnings.append(f"ROI {roi.info.name!r} covers no voxel centre of the grid: skipped")
        else:
            masks.append(m)
        report(progress, 0.2 + 0.8 * (n + 1) / len(rois), f"rasterised {roi.info.name}")
    meta = {"format": "dicom-rtstruct", "modality": "RTSTRUCT", "source": str(path), "grid": grid.note,
            "contours": rois, "series_uid": text_of(ds, "SeriesInstanceUID"),
            "rois": [{"number": r.info.value, "name": r.info.name, "contours": len(r.contours),
                      "planes": int(len(set(r.planes.tolist())))} for r in rois]}
    return segmentation_from_masks(masks, grid.shape, grid.affine, "LPS", meta, warnings)


def read_rois(ds, path, normal: Optional[np.ndarray] = None) -> Tuple[List[RoiContours], List[str]]:
    """The ROIs of an RTSTRUCT data set with their checked contours, and warnings.

    ``normal``: the stack normal (from the referenced image), else the mean of the contour normals.
    Plane positions are shared by all ROIs (``plane_t`` is the same array in each)."""
    names = {int(s.ROINumber): text_of(s, "ROIName") or f"ROI {int(s.ROINumber)}"
             for s in ds.get("StructureSetROISequence", [])}
    colours, raw, warnings = {}, {}, []
    for item in ds.get("ROIContourSequence", []):
        n = int(item.ReferencedROINumber)
        if "ROIDisplayColor" in item:
            colours[n] = tuple(round(float(c) / 255.0, 4) for c in item.ROIDisplayColor)
        raw[n] = list(item.get("ContourSequence", []))
    table = label_table_for(names, names)
    found = []
    for n, name in names.items():
        contours = []
        for c in raw.get(n, []):
            kind = text_of(c, "ContourGeometricType").upper()
            if kind == "POINT":
                break
            pts = contour_points(c)
            if kind != "CLOSED_PLANAR":
                raise AnatomeshError(f"ROI {name!r}: an {kind or 'untyped'} contour near z = {pts[:, 2].mean():.2f} mm "
                                     "is not closed; only CLOSED_PLANAR contours enclose a volume", path)
            if len(pts) < 3:
                raise AnatomeshError(f"ROI {name!r}: a contour near z = {pts[:, 2].mean():.2f} mm has "
                                     f"{len(pts)} point(s); a closed contour needs 3 or more: fix it in the "
                                     "planning system", path)
            contours.append(pts)
        if not contours:
            warnings.append(f"ROI {name!r} has no closed contour (empty or points only): skipped")
            continue
        info = dataclasses.replace(table[n], name=name, color=colours[n], color_given=True) \
            if n in colours else dataclasses.replace(table[n], name=name)
        found.append((info, contours))
    if not found:
        return [], warnings
    normal = _stack_normal([c for _, cs in found for c in cs], normal)
    return _on_planes(found, normal, path), warnings


def _newell(pts: np.ndarray) -> np.ndarray:
    """Area-weighted normal of a closed polygon (Newell's method), not normalised."""
    nxt = np.roll(pts, -1, axis=0)
    return np.array([np.sum((pts[:, 1] - nxt[:, 1]) * (pts[:, 2] + nxt[:, 2])),
                     np.sum((pts[:, 2] - nxt[:, 2]) * (pts[:, 0] + nxt[:, 0])),
                     np.sum((pts[:, 0] - nxt[:, 0]) * (pts[:, 1] + nxt[:, 1]))])


def _stack_normal(contours: List[np.ndarray], normal: Optional[np.ndarray]) -> np.ndarray:
    if normal is not None:
        return np.asarray(normal, np.float64) / np.linalg.norm(normal)
    total = np.zeros(3)
    ref = None
    for c in contours:
        nv = _newell(c)
        if ref is None and np.linalg.norm(nv) > 0:
            ref = nv
        total += nv if ref is None or nv @ ref >= 0 else -nv
    if np.linalg.norm(total) == 0:
        return np.array([0.0, 0.0, 1.0])
    total /= np.linalg.norm(total)
    return total if total[np.argmax(np.abs(total))] > 0 else -total


def _on_planes(found, normal: np.ndarray, path) -> List[RoiContours]:
    """Check planarity, plane membership and self-crossings; assign plane indices."""
    u_axis, v_axis = in_plane_axes(normal)
    ts = []
    for info, contours in found:
        for c in contours:
            t = c @ normal
            mid = float(np.median(t))
            off = float(np.abs(t - mid).max())
            where = f"ROI {info.name!r}, contour on the plane at {mid:.2f} mm"
            if off > PLANE_TOLERANCE_MM:
                raise AnatomeshError(f"{where}: its points lie up to {off:.2f} mm off any slice plane "
                                     f"(normal {np.round(normal, 4).tolist()}); contours must be planar "
                                     "and parallel: fix it in the planning system", path)
            e, f = K.first_self_crossing(c @ u_axis, c @ v_axis, 1e-9)
            if e >= 0:
                raise AnatomeshError(f"{where}: the contour crosses itself (edges {e + 1} and {f + 1} of "
                                     f"{len(c)}); fix it in the planning system", path)
            ts.append(mid)
    planes = _cluster(np.array(ts))
    out = []
    for info, contours in found:
        idx = np.array([int(np.argmin(np.abs(planes - float(np.median(c @ normal))))) for c in contours])
        out.append(RoiContours(info, contours, idx, normal, planes, str(path)))
    return out


def _cluster(t: np.ndarray, tol: float = PLANE_TOLERANCE_MM) -> np.ndarray:
    """Distinct plane positions (ascending; positions within ``tol`` are one plane)."""
    s = np.sort(t)
    groups = [[s[0]]]
    for x in s[1:]:
        if x - groups[-1][-1] <= tol:
            groups[-1].append(x)
        else:
            groups.append([x])
    return np.array([float(np.mean(g)) for g in groups])


def contour_points(item) -> np.ndarray:
    """ContourData as (n, 3) float64 mm, parsed from the raw bytes when possible (pydicom's
    DS conversion is slow on large structure sets)."""
    raw = item.get_item("ContourData")
    value = getattr(raw, "value", None)
    if isinstance(value, (bytes, bytearray)):
        return np.array(bytes(value).strip(b" \x00").split(b"\\"), dtype=np.float64).reshape(-1, 3)
    return np.asarray(item.ContourData, np.float64).reshape(-1, 3)
