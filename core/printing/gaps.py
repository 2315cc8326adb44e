"""Gaps between parts: how close every pair of parts comes, away from the seams they share.

Two parts printed closer than the printer's minimum gap fuse. :func:`part_gaps` measures the
smallest vertex-to-surface distance between every pair of parts both ways, over the uniform grid
of :class:`anatomesh.core.geometry.spatial.TriangleGrid`. Faces and vertices at identical
positions are contact by design, not gaps (:mod:`.seams`): touching parts are reported with
their seam area and the clearance away from the seam. Units are mm and mm².
"""
from __future__ import annotations

from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from ..geometry.spatial import FEATURE_EDGE, FEATURE_VERTEX, TriangleGrid
from ..model.mesh import Mesh, check_arrays, face_areas, vertex_normals
from ..model.progress import Progress, report
from .locate import location
from .profiles import GAP_REPORT_MM
from .seams import SeamIndex, seam_index, welded_part_ids


class _Parts(NamedTuple):
    """All parts of one gap search: (vertices mm, faces) each, their grids, vertex normals and
    welded vertex ids, and ``shared`` (welded ids,) bool, scratch: the ids the current pair shares."""

    parts: List[Tuple[np.ndarray, np.ndarray]]
    grids: List[Optional[TriangleGrid]]
    normals: List[np.ndarray]
    wids: List[np.ndarray]
    shared: np.ndarray


class _Seam(NamedTuple):
    """The seam of two touching parts i < j: their faces on it (bool masks), its area (mm², from
    part i) and its location (mm)."""

    faces_i: np.ndarray
    faces_j: np.ndarray
    area_mm2: float
    location: List[float]


def part_gaps(meshes: Sequence[Mesh], max_distance: float = GAP_REPORT_MM, min_gap: float = 0.0,
              grids: Optional[List[TriangleGrid]] = None, min_cos: float = 0.3,
              progress: Optional[Progress] = None) -> List[Dict]:
    """Minimum distance between every pair of parts closer than ``max_distance`` mm.

    Vertex-to-surface distances are taken both ways (from each part's vertices to the other's
    triangles). Where two parts share a seam (vertices at identical positions) the seam is
    contact by design: shared vertices are not measured from, shared faces not measured to, and
    a closest point on the seam itself does not count; the pair is reported ``touching`` with
    ``min_gap_mm`` 0 and its seam area, and ``clearance_mm`` is the distance away from the seam.
    A closest pair must face each other (|cos| ≥ ``min_cos`` between the connecting segment and
    both surfaces' normals), so points running along a surface into a seam are not gaps.

    Returns ``[{"a", "b", "ia", "ib", "touching", "seam_area_mm2", "min_gap_mm", "clearance_mm",
    "location", "fuses"}]`` with ``fuses`` when parts that do not touch are closer than
    ``min_gap`` (touching parts print joined by their seam whatever their clearance; to print
    them apart, :func:`anatomesh.core.printing.fixes.separate_parts` opens the seams).
    """
    parts = [check_arrays(m.vertices, m.faces) for m in meshes]
    names = [m.name or str(i) for i, m in enumerate(meshes)]
    if grids is None:
        grids = [TriangleGrid(v, f) if len(f) else None for v, f in parts]
    wids, nw = welded_part_ids(parts)
    normals = [vertex_normals(v, f) if len(f) else np.zeros_like(v) for v, f in parts]
    seams = seam_index(parts, wids, nw)
    ctx = _Parts(parts, grids, normals, wids, np.zeros(nw, bool))
    cand = _near_pairs(parts, max_distance)
    out = []
    for c, (i, j) in enumerate(cand):
        report(progress, c / max(len(cand), 1), f"gaps {names[i]}–{names[j]}")
        shared_ids = np.intersect1d(seams.vertices[i], seams.vertices[j], assume_unique=True)
        ctx.shared[shared_ids] = True
        seam = _shared_seam(ctx, seams, i, j) if shared_ids.size else None
        best = _closest_pair(ctx, i, j, seam, max_distance, min_cos)
        ctx.shared[shared_ids] = False
        if seam is not None or np.isfinite(best[0]):
            out.append(_gap_entry(names, i, j, seam, best, min_gap))
    report(progress, 1.0, "gaps done")
    out.sort(key=lambda d: (d["min_gap_mm"], d["clearance_mm"] if d["clearance_mm"] is not None else np.inf))
    return out


def _near_pairs(parts, max_distance: float) -> List[Tuple[int, int]]:
    """Pairs (i, j), i < j, of parts with faces whose bounding boxes (of the used vertices) are
    at most ``max_distance`` mm apart."""
    boxes = []
    for v, f in parts:
        u = v[np.unique(f.ravel())] if len(f) else np.zeros((0, 3))
        boxes.append((u.min(0), u.max(0)) if len(u) else None)
    cand = []
    for i in range(len(parts)):
        for j in range(i + 1, len(parts)):
            if boxes[i] is None or boxes[j] is None:
                continue
            sep = np.maximum(boxes[i][0] - boxes[j][1], boxes[j][0] - boxes[i][1])
            if np.linalg.norm(np.maximum(sep, 0)) <= max_distance:
                cand.append((i, j))
    return cand


def _shared_seam(ctx: _Parts, seams: SeamIndex, i: int, j: int) -> _Seam:
    """The seam of touching parts i and j (``ctx.shared`` flags the welded ids they share): the
    faces both have, their area, and where the seam is (its faces, or its shared vertices when
    the parts touch only along edges or at points)."""
    seam_i = np.zeros(len(ctx.parts[i][1]), bool)
    seam_j = np.zeros(len(ctx.parts[j][1]), bool)
    seam_i[seams.faces[i][np.isin(seams.keys[i], seams.keys[j])]] = True
    seam_j[seams.faces[j][np.isin(seams.keys[j], seams.keys[i])]] = True
    vi, fi = ctx.parts[i]
    if np.any(seam_i):
        return _Seam(seam_i, seam_j, float(face_areas(vi, fi[seam_i]).sum()),
                     location(vi[fi[seam_i]].reshape(-1, 3)))
    return _Seam(seam_i, seam_j, 0.0, location(vi[ctx.shared[ctx.wids[i]]]))


def _closest_pair(ctx: _Parts, i: int, j: int, seam: Optional[_Seam], max_distance: float,
                  min_cos: float):
    """The closest valid pair of points between parts i and j, both ways: (distance mm, point on
    one part, point on the other), or (inf, None, None)."""
    seam_i, seam_j = (None, None) if seam is None else (seam.faces_i, seam.faces_j)
    best = (np.inf, None, None)
    for a, b, seam_b in ((i, j, seam_j), (j, i, seam_i)):
        r = _one_way_gap(ctx.parts[a][0], ctx.normals[a], ctx.shared[ctx.wids[a]], ctx.grids[b],
                         ctx.parts[b][1], ctx.shared[ctx.wids[b]], seam_b, max_distance, min_cos)
        if r[0] < best[0]:
            best = r
    return best


def _gap_entry(names, i: int, j: int, seam: Optional[_Seam], best, min_gap: float) -> Dict:
    """The report entry of the pair i, j (see :func:`part_gaps`)."""
    touching = seam is not None
    clearance = best[0] if np.isfinite(best[0]) else None
    loc = seam.location if touching else location(0.5 * (best[1] + best[2]))
    entry = {"a": names[i], "b": names[j], "ia": i, "ib": j, "touching": touching,
             "seam_area_mm2": seam.area_mm2 if touching else 0.0,
             "min_gap_mm": 0.0 if touching else float(best[0]),
             "clearance_mm": None if clearance is None else float(clearance),
             "location": loc,
             # parts sharing a seam print joined anyway (separate them with
             # fixes.separate_parts): only a gap between parts apart fuses them
             "fuses": (not touching) and clearance is not None and clearance < min_gap}
    if clearance is not None and touching:
        entry["clearance_location"] = location(0.5 * (best[1] + best[2]))
    return entry


def _one_way_gap(va, na, skip_a, grid_b, fb, wb_shared_with_a, seam_b, max_d, min_cos):
    """Closest valid distance from A's vertices to B's surface: (dist, point on A, point on B).

    ``va``, ``na`` (N, 3) A's vertices (mm) and unit normals, ``skip_a`` (N,) bool its vertices
    not measured from (on the seam); ``grid_b`` and ``fb`` B's grid and faces,
    ``wb_shared_with_a`` (B's N,) bool its vertices on the seam, ``seam_b`` (B's M,) bool or None
    its faces not measured to."""
    pts = np.flatnonzero(~skip_a)
    if pts.size == 0:
        return np.inf, None, None
    lo = grid_b.origin - max_d
    hi = grid_b.origin + grid_b.dims * grid_b.cell_size + max_d
    pts = pts[np.all((va[pts] >= lo) & (va[pts] <= hi), axis=1)]
    if pts.size == 0:
        return np.inf, None, None
    d, face, q, feat = grid_b.closest(va[pts], max_d, skip_faces=seam_b, return_feature=True)
    ok = face >= 0
    fv = fb[np.maximum(face, 0)]
    ok = _off_seam(ok, feat, fv, wb_shared_with_a)
    ok = _facing(ok, va[pts], na[pts], q, grid_b.vertices, fv, min_cos)
    if not np.any(ok):
        return np.inf, None, None
    k = np.flatnonzero(ok)[np.argmin(d[ok])]
    return float(d[k]), va[pts[k]], q[k]


def _off_seam(ok, feat, fv, shared_b):
    """``ok`` cleared where the closest point is on the seam (a shared vertex, or an edge between
    shared vertices): A reaches B through the seam itself, contact by design, not a gap.
    ``feat`` (K,) the feature of each closest point (``FEATURE_VERTEX`` 0–2, ``FEATURE_EDGE``
    3–5 of :mod:`anatomesh.core.geometry.spatial`), ``fv`` (K, 3) its face's vertices."""
    for code in FEATURE_VERTEX:
        m = ok & (feat == code)
        ok[m] = ~shared_b[fv[m, code]]
    for code, (i, j) in FEATURE_EDGE.items():
        m = ok & (feat == code)
        ok[m] = ~(shared_b[fv[m, i]] & shared_b[fv[m, j]])
    return ok


def _facing(ok, p, n, q, vb, fv, min_cos):
    """``ok`` kept only where the closest pair faces each other (|cos| ≥ ``min_cos`` between the
    segment p→q and both the normal ``n`` at p and B's face normal at q), not running along
    either surface. Coincident pairs (distance 0) stay."""
    u = q - p
    ln = np.linalg.norm(u, axis=1)
    has = ok & (ln > 0)
    fn = np.cross(vb[fv[:, 1]] - vb[fv[:, 0]], vb[fv[:, 2]] - vb[fv[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    un = u / np.maximum(ln, 1e-300)[:, None]
    ca = np.abs(np.einsum("ij,ij->i", un, n))
    cb = np.abs(np.einsum("ij,ij->i", un, fn))
    ok[has] = (ca[has] >= min_cos) & (cb[has] >= min_cos)
    return ok
