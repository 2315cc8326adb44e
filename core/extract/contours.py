"""Closed planar contours (RTSTRUCT ROIs) → closed surfaces by direct tiling.

The other way to the same surfaces is rasterising the contours and extracting the label map
(:mod:`anatomesh.core.io.contour_raster` then :mod:`.multilabel`); the tests compare both.
Tiling solves the three problems of surfaces from contours (Meyers, Skinner & Sloan 1992,
"Surfaces from contours"):

* **correspondence**: on two adjacent planes, contours of the same kind (outer boundary or hole,
  by even-odd nesting) whose regions overlap belong to one piece of surface;
* **tiling**: the band between two corresponding contours is the minimum-area triangulation
  (Keppel 1975, "Approximating complex surfaces by triangulation of contour lines"; Fuchs, Kedem
  & Uselton 1977, "Optimal surface reconstruction from planar contours"), found by dynamic
  programming from the closest pair of points;
* **branching**: where one contour meets several (or several meet several), the contours of each
  side are joined into one composite contour by zero-width bridges between their closest points
  (Christiansen & Sederberg 1978, "Conversion of complex contour line definitions into polygonal
  element mosaics"), and the composites are tiled.

Contours with no partner on the next (previous) plane are capped there: the outer contour with
the unmatched holes inside it, triangulated by ear clipping after bridging the holes in (Eberly
2002, "Triangulation by ear clipping"). Every vertex is a contour point, exactly where the file
puts it; each ROI gives one closed, oriented surface.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Sequence

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.segmentation import RoiContours, in_plane_axes
from ..model.volume import space_flip
from ..geometry import polygons
from . import _contours_kernels as K


@dataclass
class _Loop:
    ids: np.ndarray      # vertex ids, outer boundaries counter-clockwise about the normal, holes clockwise
    uv: np.ndarray       # (n, 2) in-plane coordinates, mm
    plane: int
    hole: bool = False
    parent: int = -1     # index (in its plane's list) of the contour it lies in, or -1


def tile_rois(rois: Sequence[RoiContours], space: str = "LPS") -> List[Mesh]:
    """One closed surface per ROI (see the module docstring), vertices in mm in ``space``."""
    return [tile_roi(r, space) for r in rois]


def tile_roi(roi: RoiContours, space: str = "LPS") -> Mesh:
    """The closed surface of one ROI's contours by direct tiling (see the module docstring)."""
    u_axis, v_axis = in_plane_axes(roi.normal)
    vertices, planes = [], {}
    count = 0
    for pts, p in zip(roi.contours, roi.planes):
        keep = np.any(np.abs(np.diff(pts, axis=0, append=pts[:1])) > 1e-9, axis=1)
        pts = pts[keep]
        if len(pts) < 3:
            continue
        vertices.append(pts)
        planes.setdefault(int(p), []).append(_Loop(np.arange(count, count + len(pts)),
                                                   np.c_[pts @ u_axis, pts @ v_axis], int(p)))
        count += len(pts)
    if not vertices:
        raise AnatomeshError(f"ROI {roi.info.name!r} has no contour to tile", roi.source)
    for loops in planes.values():
        _nest(loops)
    verts = np.concatenate(vertices)
    faces, up, down, used = [], set(), set(), set()
    for p in sorted(planes):
        if p + 1 in planes:
            faces += _bands(planes[p], planes[p + 1], verts, up, down, used)
    step = float(np.median(np.diff(roi.plane_t))) if len(roi.plane_t) > 1 else 1.0
    extra = []
    for p, loops in planes.items():
        alone = {k for k in range(len(loops)) if (p, k) not in up and (p, k) not in down}
        faces += _caps(loops, verts, [k for k in range(len(loops)) if (p, k) not in up and k not in alone], top=True)
        faces += _caps(loops, verts, [k for k in range(len(loops)) if (p, k) not in down and k not in alone], top=False)
        for k in sorted(alone):
            base = np.concatenate([verts] + extra)
            f, v = _slab(loops[k], base, roi.normal * step / 2, len(base))
            faces += f
            extra.append(v)
    verts = np.concatenate([verts] + extra)
    tris = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    if space != "LPS":
        verts = verts @ space_flip("LPS", space)[:3, :3].T
    return Mesh(verts.astype(np.float32), tris.astype(np.int32), name=roi.info.name,
                value=roi.info.value, color=roi.info.mesh_color(), space=space,
                meta={"material": roi.info.material})


def _slab(loop: _Loop, verts, half: np.ndarray, first: int):
    """A contour alone on its plane (no partner on either side) as a prism half a plane step
    thick on each side, its contour points the middle belt: (faces, new vertices)."""
    n = len(loop.ids)
    lo, hi = first + np.arange(n), first + n + np.arange(n)
    new = np.concatenate([verts[loop.ids] - half, verts[loop.ids] + half])
    below = _band(np.asarray(lo), np.asarray(loop.ids), np.concatenate([verts, new]))
    above = _band(np.asarray(loop.ids), np.asarray(hi), np.concatenate([verts, new]))
    top = _triangulate(_Loop(hi, loop.uv, loop.plane), [])
    bottom = _triangulate(_Loop(lo, loop.uv, loop.plane), [])[:, ::-1]
    return [below, above, top, bottom], new


def _nest(loops: List[_Loop]) -> None:
    """Holes (inside an odd number of the plane's contours) and parents; orient outer boundaries
    counter-clockwise and holes clockwise about the normal."""
    holes, parents = polygons.nest([lp.uv for lp in loops])
    for lp, hole, parent in zip(loops, holes, parents):
        lp.hole, lp.parent = hole, parent
        if (polygons.signed_area(lp.uv) > 0) == lp.hole:
            lp.ids, lp.uv = lp.ids[::-1].copy(), lp.uv[::-1].copy()


def _overlap(a: _Loop, b: _Loop) -> bool:
    lo, hi = np.maximum(a.uv.min(0), b.uv.min(0)), np.minimum(a.uv.max(0), b.uv.max(0))
    if np.any(hi < lo):
        return False
    for p, q in ((a, b), (b, a)):
        if polygons.points_in_polygon(p.uv, q.uv).any():
            return True
    return False


def _bands(lower: List[_Loop], upper: List[_Loop], verts, up: set, down: set, used: set) -> List[np.ndarray]:
    """Tile every group of overlapping contours between two adjacent planes (same kind only)."""
    out = []
    for hole in (False, True):
        a = [k for k, lp in enumerate(lower) if lp.hole == hole]
        b = [k for k, lp in enumerate(upper) if lp.hole == hole]
        links = [(i, j) for i in a for j in b if _overlap(lower[i], upper[j])]
        for ga, gb in _groups(links):
            ca, pa = _composite([lower[i] for i in ga], verts, used)
            cb, pb = _composite([upper[j] for j in gb], verts, used)
            out += [_band(ca, cb, verts)] + _patch_faces(pa, True) + _patch_faces(pb, False)
            up.update((lower[i].plane, i) for i in ga)
            down.update((upper[j].plane, j) for j in gb)
    return out


def _groups(links) -> List[tuple]:
    """Connected components of the bipartite overlap graph: (lower indices, upper indices)."""
    parent: Dict = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for i, j in links:
        parent[find(("a", i))] = find(("b", j))
    comps: Dict = {}
    for i, j in links:
        comps.setdefault(find(("a", i)), (set(), set()))
        comps[find(("a", i))][0].add(i)
        comps[find(("a", i))][1].add(j)
    return [(sorted(a), sorted(b)) for a, b in comps.values()]


def _composite(loops: List[_Loop], verts, used: set):
    """One vertex-id sequence through several contours, and the bridge patches joining them.

    Contour N is spliced into the sequence S at their closest points S[a], N[b]:
    ``S[..a], N[b], N[b+1], ..., N[b-1], S[a+1..]``; the two bridges (S[a], N[b]) and
    (N[b-1], S[a+1]) and the contour edges they skip bound a flat quad in the plane, returned as
    a patch ``(S[a], S[a+1], N[b], N[b-1])`` to be triangulated with the band's orientation.
    Bridges already used on the loops' other side are avoided (an edge gets two triangles)."""
    seq = loops[0].ids
    rest, patches = list(loops[1:]), []
    while rest:
        pts = verts[seq]
        best = None
        for r, lp in enumerate(rest):
            d = np.linalg.norm(pts[:, None, :] - verts[lp.ids][None, :, :], axis=2)
            nxt, prv = np.roll(seq, -1), np.roll(lp.ids, 1)
            for x, y in used:
                d[np.ix_(np.flatnonzero(seq == x), np.flatnonzero(lp.ids == y))] = np.inf
                d[np.ix_(np.flatnonzero(nxt == x), np.flatnonzero(prv == y))] = np.inf
                d[np.ix_(np.flatnonzero(nxt == x), np.flatnonzero(lp.ids == y))] = np.inf
            a, b = np.unravel_index(int(np.argmin(d)), d.shape)
            if best is None or d[a, b] < best[0]:
                best = (d[a, b], r, a, b)
        _, r, a, b = best
        ids = np.roll(rest.pop(r).ids, -b)
        patch = (int(seq[a]), int(seq[(a + 1) % len(seq)]), int(ids[0]), int(ids[-1]))
        used.update({(patch[0], patch[2]), (patch[1], patch[3]), (patch[1], patch[2])})
        patches.append(patch)
        seq = np.concatenate([seq[:a + 1], ids, seq[a + 1:]])
    return seq, patches


def _patch_faces(patches, lower: bool) -> List[np.ndarray]:
    """Triangles of the bridge quads (S[a], S[a+1], N[b], N[b-1]); on the lower side of a band
    they use the composite's edges against its direction, on the upper side along it."""
    out = []
    for sa, sa1, nb, nb1 in patches:
        tri = np.array([[nb, sa, sa1], [nb, sa1, nb1]], np.int64)
        out.append(tri if lower else tri[:, ::-1])
    return out


def _band(ca: np.ndarray, cb: np.ndarray, verts) -> np.ndarray:
    """Minimum-area band between two id sequences, started at ca[0] and its closest point of cb.
    A band that fans one point over a whole contour (an edge used four times) is tiled again
    from other start pairs."""
    pa = np.ascontiguousarray(verts[ca])
    start = int(np.argmin(np.linalg.norm(verts[cb] - pa[0], axis=1)))
    best = None
    for shift in (0, len(cb) // 2, len(cb) // 4, 3 * len(cb) // 4):
        rolled = np.roll(cb, -(start + shift))
        local = K.band_dp(pa, np.ascontiguousarray(verts[rolled]))
        tris = np.concatenate([ca, rolled])[local]
        if best is None:
            best = tris
        if not _overused(tris):
            return tris
    return best


def _overused(tris: np.ndarray) -> bool:
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    return bool(np.unique(e, axis=0, return_counts=True)[1].max(initial=0) > 2)


def _caps(loops: List[_Loop], verts, open_loops: List[int], top: bool) -> List[np.ndarray]:
    """Close the contours without a partner on the next (``top``) or previous plane: each open
    outer boundary with the open holes inside it, and each open hole whose boundary continues."""
    out = []
    open_set = set(open_loops)
    for k in open_loops:
        lp = loops[k]
        if lp.hole and lp.parent in open_set:
            continue  # capped with its outer boundary
        holes = [loops[h] for h in open_loops if loops[h].hole and loops[h].parent == k] if not lp.hole else []
        tri = _triangulate(lp, holes)
        out.append(tri if top else tri[:, ::-1])
    return out


def _triangulate(outer: _Loop, holes: List[_Loop]) -> np.ndarray:
    """Ear clipping of a contour with its holes (:func:`anatomesh.core.geometry.polygons.triangulate`)."""
    ids = np.concatenate([outer.ids] + [h.ids for h in holes])
    return ids[polygons.triangulate(outer.uv, [h.uv for h in holes])]
