"""An independent even-odd rasterisation of RTSTRUCT contours (matplotlib's point-in-path test), to
check the reader's voxels on each contour plane: contours read with pydicom, placed on the grid by
its affine, every pixel centre tested against every contour of the ROI on that plane (XOR)."""
from __future__ import annotations

from collections import defaultdict
from typing import Dict, List

import numpy as np
from matplotlib.path import Path as PolyPath

#: a pixel centre closer than this (pixel units) to a contour edge is on it: either side is right
ON_EDGE = 1e-6


def roi_contours(ds) -> Dict[str, List[np.ndarray]]:
    """{ROI name: [(n, 3) float64 LPS mm contour points]} of the CLOSED_PLANAR contours."""
    names = {int(s.ROINumber): str(s.ROIName) for s in ds.StructureSetROISequence}
    out: Dict[str, List[np.ndarray]] = {}
    for item in ds.ROIContourSequence:
        pts = [np.asarray(c.ContourData, np.float64).reshape(-1, 3) for c in item.get("ContourSequence", [])
               if str(c.get("ContourGeometricType", "")).upper() == "CLOSED_PLANAR"]
        if pts:
            out[names[int(item.ReferencedROINumber)]] = pts
    return out


def planes_on_grid(contours: List[np.ndarray], affine: np.ndarray) -> Dict[int, List[np.ndarray]]:
    """{grid slice k: [(n, 2) contour points in (i, j) index units]}; raises when a contour is
    not on a grid slice (|k - round(k)| > 1e-3)."""
    inv = np.linalg.inv(affine)
    out: Dict[int, List[np.ndarray]] = defaultdict(list)
    for c in contours:
        idx = (inv[:3, :3] @ c.T).T + inv[:3, 3]
        k = float(np.median(idx[:, 2]))
        if abs(k - round(k)) > 1e-3:
            raise AssertionError(f"a contour lies at grid slice {k:.4f}, between slices")
        out[int(round(k))].append(idx[:, :2])
    return dict(out)


def even_odd(polys: List[np.ndarray], shape2) -> np.ndarray:
    """bool (I, J): pixel centres (i, j) inside an odd number of ``polys`` ((n, 2) index units)."""
    inside = np.zeros(shape2, bool)
    for poly in polys:
        lo = np.clip(np.floor(poly.min(axis=0)).astype(int), 0, None)
        hi = np.minimum(np.ceil(poly.max(axis=0)).astype(int) + 1, shape2)
        if np.any(hi <= lo):
            continue
        ii, jj = np.meshgrid(np.arange(lo[0], hi[0]), np.arange(lo[1], hi[1]), indexing="ij")
        hit = PolyPath(poly).contains_points(np.c_[ii.ravel(), jj.ravel()]).reshape(ii.shape)
        inside[lo[0]:hi[0], lo[1]:hi[1]] ^= hit
    return inside


def edge_distance(points: np.ndarray, polys: List[np.ndarray]) -> np.ndarray:
    """(P,) distance (index units) of each point (P, 2) to the nearest edge of ``polys``."""
    best = np.full(len(points), np.inf)
    for poly in polys:
        a, b = poly, np.roll(poly, -1, axis=0)
        ab = b - a
        length2 = np.maximum((ab ** 2).sum(axis=1), 1e-300)
        for chunk in range(0, len(points), 256):
            p = points[chunk:chunk + 256, None, :]
            t = np.clip(((p - a) * ab).sum(axis=2) / length2, 0.0, 1.0)
            d = np.linalg.norm(p - (a + t[..., None] * ab), axis=2).min(axis=1)
            best[chunk:chunk + 256] = np.minimum(best[chunk:chunk + 256], d)
    return best


def compare_plane(ours: np.ndarray, polys: List[np.ndarray]):
    """(pixels set by the reader, pixels set by even-odd, pixels that differ and are not on an
    edge) for one contour plane; ``ours`` bool (I, J)."""
    truth = even_odd(polys, ours.shape)
    diff = np.argwhere(ours != truth)
    off_edge = int(np.count_nonzero(edge_distance(diff.astype(np.float64), polys) > ON_EDGE)) if len(diff) else 0
    return int(ours.sum()), int(truth.sum()), off_edge
