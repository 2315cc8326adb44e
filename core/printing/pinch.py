"""Pinches: where two parts of one solid hold together through less than the minimum wall, though
the material on either side is thick — so no thin sheet, rod or rim shows it. A print breaks
there, or prints as two loose pieces.

Three ways a part is pinched, each found on its own (:func:`pinches`):

* *touching pieces*: two shells of the part meet at a point or along a line, with their vertices
  at the same position there (the surface meets itself: vertices around which, with positions
  welded, the faces form more than one fan);
* *nearly touching pieces*: two shells closer than the printer's minimum gap, so the printer
  fuses them, where they meet over a patch narrower than the minimum wall (a point or a line,
  not a face): no material joins them that a print could rely on;
* *a neck*: within one shell, a vertex on a concave crease whose inward direction (the mean of
  its faces' inward normals: at a crease between two lobes, the way across their join) leaves
  the solid in less than the minimum wall: a waist between two lobes. Its material lies within
  the part's full-thickness body (each lobe's balls reach it), so the thin-feature rule, which
  measures how far thin material reaches beyond that body, passes it. When that ray meets the
  surface from outside (it crossed no material but a gap between two lobes that nearly touch,
  as where a mesher parted the pieces of a pinch point by a few hundredths of a mm), the place
  is two pieces nearly touching within one shell, reported as such when the gap is below the
  minimum gap (a wider gap stays open: no pinch).

Each pinch is a region of the report like the thin features (:mod:`.features`): ``kind``
"pinch", its ``thickness_mm`` (the width of the material joining the two sides: 0 for pieces
that touch or nearly touch), ``gap_mm`` (how far apart nearly touching pieces are), ``length_mm``
(how far it runs: 0 for a point), its location and a reason that says what to do (thicken the
part, join the pieces, or print them as separate pieces). Units are mm.
"""
from __future__ import annotations

from typing import Dict, List, Optional

import numpy as np

from ..geometry.kernels import union_find_roots
from ..geometry.spatial import TriangleGrid
from ..geometry.topology import edge_face_counts, face_components, nonmanifold_vertices
from ..model.mesh import weld_ids
from .features import vertex_inward
from .locate import location, location_text
from .profiles import CONTACT_MM

#: a vertex is on a concave crease when its neighbours rise above its tangent plane by this
#: fraction of their distance, on average (a 90° crease cut by one row of faces: ~0.3)
_CONCAVE = 0.1


def pinches(vertices: np.ndarray, faces: np.ndarray, details: Dict, min_wall: float, min_gap: float,
            grid: Optional[TriangleGrid] = None, exclude: Optional[np.ndarray] = None) -> List[Dict]:
    """The pinches of a part (module docstring), each a failing region: ``kind`` "pinch",
    ``vertices`` (index array), ``location``, ``thickness_mm``, ``extent`` (``{"length_mm"}``),
    ``gap_mm`` (pieces nearly touching: how far apart; else 0), ``area_mm2`` 0, ``min_mm`` and
    ``median_mm`` (the thickness), ``min_location``, ``reason``.

    ``vertices`` (N, 3) mm and ``faces`` (M, 3): the part; ``details`` of
    :func:`.thickness.wall_thickness` (``"inward"``: the faces' inward directions); ``min_wall``
    and ``min_gap`` mm from the profile; ``exclude`` (N,) bool: vertices of thin features
    already failing (a sheet's concave side is no neck)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    if f.shape[0] == 0:
        return []
    g = grid if grid is not None else TriangleGrid(v, f)
    found = _touching(v, f) + _near_pieces(v, f, min_wall, min_gap)
    skip = np.zeros(len(v), bool) if exclude is None else np.asarray(exclude, bool).copy()
    for r in found:  # a place already found is not found again from within a shell
        skip[r["vertices"]] = True
    found += _necks(v, f, details, min_wall, min_gap, g, skip)
    for r in found:
        _finish(r, v, min_wall, min_gap)
    return found


def _touching(v: np.ndarray, f: np.ndarray) -> List[Dict]:
    """Pieces meeting where the surface meets itself, positions welded: vertices with their faces
    in more than one fan, and edges of more than two faces (two shells sharing a line)."""
    wid = weld_ids(v)
    nw = int(wid.max()) + 1
    wf = wid[f]
    edges, count, _ = edge_face_counts(wf, nw)
    bad = np.union1d(nonmanifold_vertices(wf, nw), edges[count > 2].ravel())
    if bad.size == 0:
        return []
    pick = np.flatnonzero(np.isin(wid, bad))
    order = pick[np.argsort(wid[pick], kind="stable")]
    same = wid[order][1:] == wid[order][:-1]
    links = np.stack([order[:-1][same], order[1:][same]], axis=1)
    return [{"vertices": g, "thickness_mm": 0.0, "gap_mm": 0.0, "how": "touch"}
            for g in _groups(f, pick, len(v), links=links)]


def _near_pieces(v: np.ndarray, f: np.ndarray, min_wall: float, min_gap: float) -> List[Dict]:
    """Pairs of shells (welded) closer than ``min_gap`` whose closest approach is narrower than
    ``min_wall``: the vertices of each within ``CONTACT_MM`` plus the smallest distance of the
    other, spread less than ``min_wall`` in their second principal direction."""
    wid = weld_ids(v)
    n, lab = face_components(wid[f], int(wid.max()) + 1)
    if n < 2:
        return []
    shells = [f[lab == c] for c in range(n)]
    verts = [np.unique(s.ravel()) for s in shells]
    lo = np.array([v[x].min(0) for x in verts])
    hi = np.array([v[x].max(0) for x in verts])
    grids: Dict[int, TriangleGrid] = {}
    out = []
    for i in range(n):
        for j in range(i + 1, n):
            if np.any(lo[i] - hi[j] > min_gap) or np.any(lo[j] - hi[i] > min_gap):
                continue
            zone, gap = _contact_zone(v, shells, verts, grids, i, j, min_gap)
            if zone is not None and _spread(v[zone])[1] < min_wall:
                out.append({"vertices": zone, "thickness_mm": 0.0, "gap_mm": gap, "how": "near"})
    return out


def _contact_zone(v, shells, verts, grids, i: int, j: int, min_gap: float):
    """(vertices of shells i and j within ``CONTACT_MM`` of their smallest distance to the other,
    that distance mm), or (None, inf) when they are ``min_gap`` or more apart."""
    d = []
    for a, b in ((i, j), (j, i)):
        if b not in grids:
            grids[b] = TriangleGrid(v, shells[b])
        d.append(grids[b].closest(v[verts[a]], max_distance=min_gap)[0])
    gap = float(min(d[0].min(), d[1].min()))
    if not gap < min_gap:
        return None, np.inf
    zone = np.concatenate([verts[i][d[0] <= gap + CONTACT_MM], verts[j][d[1] <= gap + CONTACT_MM]])
    return zone, gap


def _necks(v, f, details: Dict, min_wall: float, min_gap: float, g: TriangleGrid,
           exclude: np.ndarray) -> List[Dict]:
    """Necks within a shell (module docstring): vertices on a concave crease
    (:func:`_concave`), not in ``exclude`` (N,) bool (the thin features already failing),
    whose inward direction leaves the solid within ``min_wall`` (a neck), or meets the surface from
    outside within ``min_gap`` (two lobes nearly touching); grouped with where the ray ends."""
    fa = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    inward = vertex_inward(f, len(v), details["inward"], fa)
    cand = np.flatnonzero(~exclude & (np.linalg.norm(inward, axis=1) > 0) & _concave(v, f, inward))
    if cand.size == 0:
        return []
    span = max(float(np.ptp(v, axis=0).max()), 1e-3)
    across, face, _, _ = g.cast(v[cand], inward[cand], t_min=1e-6 * span, t_max=min_wall)
    hit = face >= 0
    outside = np.zeros(cand.size, bool)  # the ray crossed a gap, not material
    outside[hit] = np.einsum("ij,ij->i", inward[cand[hit]], details["inward"][face[hit]]) > 0
    ok = hit & np.where(outside, across < min_gap, across < min_wall)
    out = []
    for how, sel in (("neck", ok & ~outside), ("near", ok & outside)):
        out += _neck_groups(v, f, cand[sel], face[sel], across[sel], inward, how)
    return out


def _neck_groups(v, f, src: np.ndarray, face: np.ndarray, across: np.ndarray, inward: np.ndarray,
                 how: str) -> List[Dict]:
    """Pinch regions from rays cast from vertices ``src`` along ``inward`` that ended on ``face``
    after ``across`` mm: each ray's vertex and the corner of its face nearest the end, grouped."""
    if src.size == 0:
        return []
    end = v[src] + across[:, None] * inward[src]
    corner = f[face, np.argmin(np.linalg.norm(v[f[face]] - end[:, None], axis=2), axis=1)]
    width = np.full(len(v), np.inf)
    np.minimum.at(width, src, across)
    out = []
    for grp in _groups(f, np.union1d(src, corner), len(v), links=np.stack([src, corner], 1)):
        k = np.argmin(width[grp])
        w = float(width[grp][k])
        out.append({"vertices": grp, "thickness_mm": w if how == "neck" else 0.0,
                    "gap_mm": 0.0 if how == "neck" else w, "how": how, "narrowest": grp[k]})
    return out


def _concave(v: np.ndarray, f: np.ndarray, inward: np.ndarray) -> np.ndarray:
    """(N,) bool: vertices whose neighbours lie outside their tangent plane by more than
    :data:`_CONCAVE` of the mean edge around them (on average): a concave crease or dimple."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = np.concatenate([e, e[:, ::-1]])
    d = v[e[:, 1]] - v[e[:, 0]]
    rise = -np.einsum("ij,ij->i", d, inward[e[:, 0]])
    n = np.bincount(e[:, 0], minlength=len(v))
    mean_rise = np.bincount(e[:, 0], rise, minlength=len(v)) / np.maximum(n, 1)
    mean_edge = np.bincount(e[:, 0], np.linalg.norm(d, axis=1), minlength=len(v)) / np.maximum(n, 1)
    return mean_rise > _CONCAVE * mean_edge


def _groups(f: np.ndarray, pick: np.ndarray, n: int, links: Optional[np.ndarray] = None) -> List[np.ndarray]:
    """The vertices ``pick`` split into groups joined by mesh edges (and ``links`` (K, 2) pairs)."""
    on = np.zeros(n, bool)
    on[pick] = True
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    if links is not None:
        e = np.concatenate([e, links])
    e = e[on[e[:, 0]] & on[e[:, 1]]]
    roots = union_find_roots(np.ascontiguousarray(e[:, 0], np.int64), np.ascontiguousarray(e[:, 1], np.int64), n)
    _, lab = np.unique(roots[pick], return_inverse=True)
    return [pick[lab == k] for k in range(lab.max() + 1)] if pick.size else []


def _spread(p: np.ndarray) -> np.ndarray:
    """Extents (3,) mm of points ``p`` (K, 3) along their principal directions, largest first."""
    q = p - p.mean(axis=0)
    if len(q) < 2:
        return np.zeros(3)
    _, _, axes = np.linalg.svd(q, full_matrices=False)
    proj = q @ axes.T
    ext = np.zeros(3)
    ext[:proj.shape[1]] = np.ptp(proj, axis=0)
    return ext


def _finish(r: Dict, v: np.ndarray, min_wall: float, min_gap: float):
    """The report fields of a pinch ``r`` (in place): location, measures, reason."""
    p = v[r["vertices"]]
    length = float(_spread(p)[0])
    loc = location(p) if "narrowest" not in r else location(v[r.pop("narrowest")])
    at = location_text(loc)
    where = f"along a line {length:.1f} mm long" if length >= min_wall else "at a point"
    how = r.pop("how")
    if how == "neck":
        what = (f"pinch {r['thickness_mm']:.2f} mm across {where} at {at}: a neck between two thick parts, "
                f"thinner than the {min_wall:g} mm minimum wall; thicken it (dilate the label there)")
    else:
        meet = "touch" if how == "touch" else f"are {r['gap_mm']:.2f} mm apart (under the {min_gap:g} mm gap)"
        what = (f"pinch at {at}: two pieces of the part {meet} {where}, joined by less than the "
                f"{min_wall:g} mm minimum wall; join them (a connector, or dilate the label) or print them apart")
    r.update(kind="pinch", fails=True, location=loc, min_location=loc, extent={"length_mm": round(length, 2)},
             area_mm2=0.0, reach_area_mm2=0.0, min_mm=r["thickness_mm"], median_mm=r["thickness_mm"],
             reason=what)
