"""Closed planar contours → voxel masks: exact even-odd rasterisation on each contour plane and
shape-based interpolation between planes.

* On a contour plane, a pixel is inside when its centre is inside an odd number of the ROI's
  contours on that plane (even-odd rule: a contour inside a contour is a hole; several disjoint
  contours are several islands). Rasterised at pixel centres this reproduces reference voxel
  masks (e.g. MIRP's) exactly.
* Between two adjacent contour planes, ``factor - 1`` planes are filled by shape-based
  interpolation: the signed distance maps of the two planes' masks (Euclidean, in mm) are blended
  linearly and thresholded at zero (Raya & Udupa 1990, "Shape-based interpolation of
  multidimensional objects"; Herman, Zheng & Bucholtz 1992). A plane without contours of the ROI
  ends it: no interpolation across it.

The grid: the referenced CT's in-plane lattice (origin, axes, pixel spacing) when known, else the
patient x/y axes projected into the contour planes at 1 mm; the slice planes every ``step /
factor`` from the first contour plane to the last, ``step`` being the CT's slice step (when its
slices hold every contour plane) or the contour planes' own.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Optional

import numpy as np

from ..model.errors import AnatomeshError
from ..model.segmentation import Mask, RoiContours, crop_mask, in_plane_axes
from . import _contour_kernels as K
from .plane_lattice import fitted_lattice, lattice_offsets

#: contour planes further than this from the slice lattice (fraction of the step) are off-plane
LATTICE_TOLERANCE = 0.05
#: target slice step of the meshing grid as a multiple of the pixel size (sets ``factor``)
SLICE_TO_PIXEL = 1.5
NATIVE_PIXEL_MM = 1.0


@dataclass
class ContourGrid:
    """The grid ROIs are rasterised on: ``affine`` (index → LPS mm), ``shape``; ``plane_k[p]``:
    the grid slice of contour plane p; ``factor``: grid slices per contour-plane step; ``note``."""

    affine: np.ndarray
    shape: tuple
    plane_k: np.ndarray
    factor: int
    note: str = ""


def contour_grid(rois: List[RoiContours], ref=None, use_image: bool = True, path=None,
                 factor: Optional[int] = None, pixel_mm: Optional[float] = None) -> ContourGrid:
    """The grid for ``rois`` (all on one stack of planes); ``ref`` the referenced image
    (:class:`~anatomesh.core.io.dicom_objects.ReferenceGrid`) or None. ``factor``: grid slices per
    plane step (default: so the slice step is about 1.5 pixels); ``pixel_mm`` forces the in-plane
    spacing (native grids only)."""
    normal, planes = rois[0].normal, rois[0].plane_t
    plane = ref.plane if ref is not None else None
    if plane is not None:
        row, col, (dx, dy), origin = plane["row"], plane["col"], plane["spacing"], plane["origin"]
        what = "the referenced CT's pixel lattice"
    else:
        row, col = in_plane_axes(normal)
        dx = dy = float(pixel_mm or NATIVE_PIXEL_MM)
        origin = np.zeros(3)
        what = f"the contour planes at {dx:g} mm pixels"
    step, t0, note = _slice_lattice(planes, ref if use_image else None, path)
    k_plane = np.round((planes - t0) / step).astype(np.int64)
    f = int(factor or max(1, math.ceil(step / (SLICE_TO_PIXEL * min(dx, dy)) - 1e-9)))
    pts = np.concatenate([c for r in rois for c in r.contours])
    a = (pts - origin) @ row / dx
    b = (pts - origin) @ col / dy
    lo = np.array([math.floor(a.min()) - 1, math.floor(b.min()) - 1])
    hi = np.array([math.ceil(a.max()) + 1, math.ceil(b.max()) + 1])
    first = int(k_plane.min())
    affine = np.eye(4)
    affine[:3, 0], affine[:3, 1], affine[:3, 2] = row * dx, col * dy, normal * (step / f)
    affine[:3, 3] = origin + row * dx * lo[0] + col * dy * lo[1] + normal * (t0 + first * step - origin @ normal)
    shape = (int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1), int((k_plane.max() - first) * f + 1))
    note = (f"{what}; {len(planes)} contour planes every {step:g} mm{note}, "
            f"{f} grid slice{'s' * (f > 1)} per plane step ({step / f:.3g} mm), {'x'.join(map(str, shape))} voxels")
    return ContourGrid(affine, shape, (k_plane - first) * f, f, note)


def _slice_lattice(planes: np.ndarray, ref, path):
    """(step, t0, note): the slice lattice the contour planes lie on."""
    if ref is not None and ref.plane is not None and len(ref.plane["positions"]) > 1:
        n = np.cross(ref.plane["row"], ref.plane["col"])
        t_ct = np.sort(ref.plane["positions"] @ n)
        step = float(np.median(np.diff(t_ct)))
        k = (planes - t_ct[0]) / step
        if np.abs(k - np.round(k)).max() <= LATTICE_TOLERANCE:
            return step, float(t_ct[0]), " (on the CT's slices)"
    if len(planes) == 1:
        return 1.0, float(planes[0]), ""
    step, t0 = fitted_lattice(planes, float(np.diff(planes).min()))
    off = lattice_offsets(planes, step)
    if off.max() > LATTICE_TOLERANCE:
        bad = int(np.argmax(off))
        raise AnatomeshError(f"the contour plane at {planes[bad]:.2f} mm is off the slice lattice (step "
                             f"{step:.4g} mm through the other planes) by {off[bad] * step:.2f} mm ({off[bad]:.2f} "
                             f"of a step; tolerance {LATTICE_TOLERANCE:g}), so the contours cannot be stacked; "
                             "move that contour onto an image slice in the planning system and export the "
                             "structure set again", path)
    return step, t0, ""


def plane_masks(roi: RoiContours, grid: ContourGrid) -> Dict[int, np.ndarray]:
    """Even-odd mask (uint8, full in-plane grid (I, J)) of each contour plane of the ROI."""
    inv = np.linalg.inv(grid.affine)
    out = {}
    for p in sorted(set(int(q) for q in roi.planes)):
        cs = roi.on_plane(p)
        idx = (inv[:3, :3] @ np.concatenate(cs).T).T + inv[:3, 3]
        starts = np.cumsum([0] + [len(c) for c in cs]).astype(np.int64)
        m = np.zeros(grid.shape[:2], np.uint8)
        K.even_odd_fill(np.ascontiguousarray(idx[:, 0]), np.ascontiguousarray(idx[:, 1]), starts,
                        grid.shape[0], grid.shape[1], m)
        out[p] = m
    return out


def rasterise_roi(roi: RoiContours, grid: ContourGrid) -> Optional[Mask]:
    """The ROI's voxels on ``grid`` (contour planes exact, planes between interpolated by shape),
    cropped to its box; None when no voxel centre is inside."""
    masks = plane_masks(roi, grid)
    box = _box(list(masks.values()))
    if box is None:
        return None
    (i0, i1), (j0, j1) = box
    ps = sorted(masks)
    k0, k1 = int(grid.plane_k[ps[0]]), int(grid.plane_k[ps[-1]])
    data = np.zeros((i1 - i0, j1 - j0, k1 - k0 + 1), bool)
    dist = {}
    for p in ps:
        data[:, :, grid.plane_k[p] - k0] = masks[p][i0:i1, j0:j1] != 0
    spacing = np.linalg.norm(grid.affine[:3, :2], axis=0)
    for p, q in zip(ps[:-1], ps[1:]):
        gap = int(grid.plane_k[q] - grid.plane_k[p])
        if gap != grid.factor or grid.factor == 1:
            continue
        for r in (p, q):
            if r not in dist:
                dist[r] = signed_distance(data[:, :, grid.plane_k[r] - k0], spacing)
        for m in range(1, gap):
            w = m / gap
            data[:, :, grid.plane_k[p] - k0 + m] = (1.0 - w) * dist[p] + w * dist[q] > 0
    return crop_mask(roi.info, data, (i0, j0, k0))


def signed_distance(mask: np.ndarray, spacing) -> np.ndarray:
    """Signed Euclidean distance (mm) to the mask's border, positive inside, zero half-way between
    an inside and an outside pixel centre (Raya & Udupa 1990). An empty or full mask gives a large
    negative or positive constant."""
    from scipy import ndimage

    if not mask.any():
        return np.full(mask.shape, -1e6)
    if mask.all():
        return np.full(mask.shape, 1e6)
    inside = ndimage.distance_transform_edt(mask, sampling=spacing)
    outside = ndimage.distance_transform_edt(~mask, sampling=spacing)
    half = 0.5 * float(min(spacing))
    return np.where(mask, inside - half, half - outside)


def _box(masks: List[np.ndarray]):
    any2d = np.zeros_like(masks[0], bool)
    for m in masks:
        any2d |= m != 0
    ii, jj = np.flatnonzero(any2d.any(axis=1)), np.flatnonzero(any2d.any(axis=0))
    if not len(ii):
        return None
    # one pixel of margin so interpolated planes may grow a little past the contour planes' union
    return ((max(0, ii[0] - 1), min(any2d.shape[0], ii[-1] + 2)),
            (max(0, jj[0] - 1), min(any2d.shape[1], jj[-1] + 2)))
