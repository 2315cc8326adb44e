"""Wall thickness of a printed part: how thick the solid is at each face and vertex, in mm, and
where it is thinner than the printer can build.

* :func:`face_thickness` at each face's centroid: a ray cast inwards (inward chosen by crossing
  parity, not by the normals' sign) cross-checked with the shrinking-ball inscribed sphere (Ma,
  Bae & Kobbelt 2012, "3D medial axis point approximation using nearest neighbors and the
  normal field");
* :func:`wall_thickness` per vertex: the thinnest face around it, raised to the diameter of the
  largest inscribed ball reaching it (Hildebrand & Rüegsegger 1997, "A new method for the
  model-independent assessment of thickness in three-dimensional images");
* :func:`thin_regions` groups thin vertices into connected regions with location and area;
  :func:`robust_min_wall` is the thinnest wall outside the isolated spots it leaves out.

Rays and balls are answered by :class:`anatomesh.core.geometry.spatial.TriangleGrid`.
"""
from __future__ import annotations

from typing import Dict, List, Optional

import numpy as np

from ..geometry.kernels import union_find_roots
from ..geometry.spatial import TriangleGrid
from ..geometry.topology import closed_and_oriented, face_components
from ..model.errors import AnatomeshError
from ..model.mesh import check_arrays, vertex_areas
from .locate import location

#: a ball estimate below this fraction of the ray estimate is a collapsed ball at a sharp edge
_BALL_RAY_RATIO = 0.5
#: shrinking stops at a surface point seen from the ball's centre within ~100° of the start: it
#: is the vertex's own side (curvature, facets, a tilted normal), not the opposite wall
_SEPARATION_COS = -0.2
#: a vertex within this many mean edge lengths of an inscribed ball's sphere is reached by it
_COVER_PAD = 0.25


def _inward_rays(grid: TriangleGrid, origins: np.ndarray, n: np.ndarray, t_min: float):
    """Cast along −n and +n from each origin; keep the direction with odd crossing parity (a
    point just along it is inside the solid), whatever the sign of ``n``.

    Returns (unit inward direction (K, 3), first-hit distance (K,) mm, decided (K,) bool)."""
    rng = np.random.default_rng(12345)
    k = len(origins)
    dirs = np.zeros((k, 3))
    t_hit = np.full(k, np.inf)
    decided = np.zeros(k, bool)
    todo = np.arange(k)
    for attempt in range(3):
        if todo.size == 0:
            break
        base = n[todo]
        if attempt:  # tilt a little to avoid hitting edges or vertices exactly
            jitter = rng.normal(size=base.shape)
            base = base + 0.02 * attempt * jitter / np.linalg.norm(jitter, axis=1, keepdims=True)
        for sign in (-1.0, 1.0):
            if todo.size == 0:
                break
            d = sign * base
            t, _, nc, amb = grid.cast(origins[todo], d, t_min=t_min, count_all=True)
            ok = (nc % 2 == 1) & ~amb
            dirs[todo[ok]] = d[ok] / np.linalg.norm(d[ok], axis=1, keepdims=True)
            t_hit[todo[ok]] = t[ok]
            decided[todo[ok]] = True
            todo, base = todo[~ok], base[~ok]
    if todo.size:  # open or broken surface: fall back to the normals' own inward side
        d = -n[todo]
        t, _, _, _ = grid.cast(origins[todo], d, t_min=t_min)
        dirs[todo] = d
        t_hit[todo] = t
    return dirs, t_hit, decided


def _oriented_rays(grid, v, f, idx, origins, n, t_min, max_thickness):
    """Inward rays for a closed, consistently oriented surface: per connected component, parity
    rays from its three largest faces vote whether its normals point outward; then one
    first-hit ray per face. Returns like :func:`_inward_rays`."""
    ncomp, lab = face_components(f, len(v))
    lab = lab[idx]
    area = np.linalg.norm(np.cross(v[f[idx, 1]] - v[f[idx, 0]], v[f[idx, 2]] - v[f[idx, 0]]), axis=1)
    order = np.lexsort((-area, lab))
    first = np.r_[0, np.flatnonzero(np.diff(lab[order])) + 1]
    votes = []
    for k in range(3):
        pick = order[np.minimum(first + k, np.r_[first[1:], order.size] - 1)]
        _, _, nc, amb = grid.cast(origins[pick], -n[pick], t_min=t_min, count_all=True)
        votes.append(np.where(amb, 0, np.where(nc % 2 == 1, 1, -1)))
    comp_sign = np.where(np.sum(votes, axis=0) >= 0, 1.0, -1.0)
    sign = np.ones(ncomp)
    sign[lab[order[first]]] = comp_sign
    dirs = -sign[lab][:, None] * n
    t_max = np.inf if max_thickness is None else float(max_thickness)
    t, _, _, _ = grid.cast(origins, dirs, t_min=t_min, t_max=t_max)
    return dirs, t, np.ones(len(idx), bool)


def face_thickness(vertices: np.ndarray, faces: np.ndarray, grid: Optional[TriangleGrid] = None,
                   max_thickness: Optional[float] = None, oriented: Optional[bool] = None,
                   return_details: bool = False):
    """Local wall thickness at each face's centroid, (M,) float64 mm (NaN for zero-area faces).

    The minimum of two estimates along the face's inward normal:

    * ray: distance from the centroid to the opposite surface. "Inward" is the side where the
      ray crosses the surface an odd number of times (a point just along it is inside), so
      flipped or inconsistent normals do not matter;
    * ball: diameter of the largest empty ball touching the centroid with its centre on the
      inward line (shrinking ball, Ma, Bae & Kobbelt 2012), started at half the ray length. It
      corrects rays that leave obliquely. A ball under half the ray length is the collapse of
      the tangent ball near a convex edge or corner, not a thin wall, and is not used.

    On a closed, consistently oriented surface (``oriented``; default: checked with
    :func:`anatomesh.core.geometry.topology.closed_and_oriented`) one parity ray per connected
    component tells whether that component's normals point out or in, and each face then needs only its first hit; on
    any other surface every face decides its inward side by parity itself.

    Face centroids are used rather than vertices because a face's normal is exact while a
    vertex normal at a crease or a staircase step is an average that sends rays across corners.
    ``max_thickness`` (mm) bounds the rays and the ball search (its cost grows with the cube of
    the radius): thicker walls come out as ``max_thickness``. With ``return_details`` also returns
    ``{"ray", "ball" (M,) mm, "decided" (M,) bool, "centre" (M, 3) mm, "inscribed" (M,) bool,
    "inward" (M, 3)}``: decided False where parity could not tell the inside (e.g. on an open
    surface); the inscribed ball's centre and whether it is a valid (empty) one; the unit inward
    direction (zero for zero-area faces).
    """
    v, f = check_arrays(vertices, faces)
    m = f.shape[0]
    out = np.full(m, np.nan)
    details = {"ray": np.full(m, np.nan), "ball": np.full(m, np.nan), "decided": np.zeros(m, bool),
               "centre": np.full((m, 3), np.nan), "inscribed": np.zeros(m, bool),
               "inward": np.zeros((m, 3))}
    if m == 0:
        return (out, details) if return_details else out
    g = grid if grid is not None else TriangleGrid(v, f)
    p = v[f]
    cen = p.mean(axis=1)
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ln = np.linalg.norm(fn, axis=1)
    span = float(np.ptp(p.reshape(-1, 3), axis=0).max())
    ok = ln > 1e-12 * max(span, 1e-6) ** 2
    idx = np.flatnonzero(ok)
    n = fn[idx] / ln[idx, None]
    t_min = 1e-7 * max(span, 1e-3)
    if oriented is None:
        oriented = closed_and_oriented(f, len(v))
    if oriented:
        dirs, ray, decided = _oriented_rays(g, v, f, idx, cen[idx], n, t_min, max_thickness)
    else:
        dirs, ray, decided = _inward_rays(g, cen[idx], n, t_min)
    if max_thickness is not None:
        ray = np.minimum(ray, float(max_thickness))
    r0 = np.where(np.isfinite(ray), 0.5 * ray, 0.5 * span)
    if max_thickness is not None:
        if not max_thickness > 0:
            raise AnatomeshError(f"max_thickness must be a positive number of mm, got {max_thickness}")
        r0 = np.minimum(r0, 0.5 * float(max_thickness))
    r, empty = g.shrinking_balls(cen[idx], dirs, r0, min_sep_cos=_SEPARATION_COS)
    ball = 2.0 * r
    sensible = ~(ball < _BALL_RAY_RATIO * ray)
    out[idx] = np.where(sensible, np.fmin(ray, ball), ray)
    if return_details:
        details["ray"][idx] = ray
        details["ball"][idx] = ball
        details["decided"][idx] = decided
        details["centre"][idx] = cen[idx] + r[:, None] * dirs
        details["inscribed"][idx] = empty & sensible
        details["inward"][idx] = dirs
        return out, details
    return out


def wall_thickness(vertices: np.ndarray, faces: np.ndarray, grid: Optional[TriangleGrid] = None,
                   max_thickness: Optional[float] = None, oriented: Optional[bool] = None,
                   return_details: bool = False):
    """Local wall thickness at each vertex, (N,) float64 mm (NaN for vertices no face uses).

    Two views, the larger wins:

    * the thinnest :func:`face_thickness` of the faces around the vertex (a vertex on a thin
      plate is thin even where it also bounds the plate's rim);
    * the diameter of the largest inscribed ball that reaches the vertex (Hildebrand &
      Rüegsegger 1997, "A new method for the model-independent assessment of thickness in
      three-dimensional images"), using the empty balls found by the shrinking-ball step.
      Near convex edges and corners the tangent estimates shrink to nothing, while the balls of
      the neighbouring wall still reach there: this keeps rims and corners at the wall's own
      thickness instead of reporting every edge as thin.

    Same options as :func:`face_thickness`; ``return_details`` adds ``"face"`` (M,) mm."""
    v, f = check_arrays(vertices, faces)
    ft, det = face_thickness(v, f, grid, max_thickness, oriented, return_details=True)
    out = np.full(len(v), np.inf)
    vals = np.where(np.isnan(ft), np.inf, ft)
    for k in range(3):
        np.minimum.at(out, f[:, k].astype(np.int64), vals)
    out[~np.isfinite(out)] = np.nan
    ins = np.flatnonzero(det["inscribed"])
    if ins.size:
        used = np.unique(f.ravel())
        pts = TriangleGrid(v, np.repeat(used[:, None], 3, axis=1).astype(np.int32),
                           cell_size=_point_cell(v, f))
        edge = float(np.mean(np.linalg.norm(v[f[:, 1]] - v[f[:, 0]], axis=1)))
        cover = np.zeros(len(v))
        pts.ball_cover(det["centre"][ins], 0.5 * det["ball"][ins], _COVER_PAD * edge,
                       used[pts.items].astype(np.int32), cover)
        out = np.where(np.isnan(out), out, np.fmax(out, np.where(cover > 0, cover, np.nan)))
    if return_details:
        det["face"] = ft
        return out, det
    return out


def _point_cell(v, f) -> float:
    e = np.linalg.norm(v[f[:, 1]] - v[f[:, 0]], axis=1)
    return max(2.0 * float(np.mean(e)), 1e-6)


def thin_regions(vertices: np.ndarray, faces: np.ndarray, thickness: np.ndarray,
                 min_wall: float, min_area_mm2: Optional[float] = None,
                 min_vertices: int = 3, links: Optional[np.ndarray] = None) -> List[Dict]:
    """Connected regions of vertices thinner than ``min_wall`` mm (linked by mesh edges, and by
    ``links`` (K, 2) vertex pairs if given: e.g. the two sides of a sheet).

    Regions smaller than ``min_area_mm2`` (default ``min_wall²``: less than one printed line by
    one printed line) or of fewer than ``min_vertices`` vertices are isolated spots — a sharp
    corner, a crease where smoothed organs meet, or a staircase step where tangent estimates
    vanish — and are left out (on a coarse mesh one vertex alone can stand for ~10 mm²).

    Returns ``[{"vertices": index array, "location": centroid mm, "area_mm2", "min_mm",
    "median_mm" (area-weighted), "min_location"}]``, largest area first. Thin branches (vessels,
    ribs) show up as regions whose ``min_mm`` is the smallest diameter along them."""
    v, f = check_arrays(vertices, faces)
    t = np.asarray(thickness, np.float64)
    if t.shape != (len(v),):
        raise AnatomeshError(f"thickness must have one value per vertex ({len(v)}), got {t.shape}")
    min_area = float(min_wall) ** 2 if min_area_mm2 is None else float(min_area_mm2)
    thin = np.isfinite(t) & (t < min_wall)
    if not np.any(thin) or f.shape[0] == 0:
        return []
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]).astype(np.int64)
    if links is not None and len(links):
        e = np.concatenate([e, np.asarray(links, np.int64).reshape(-1, 2)])
    e = e[thin[e[:, 0]] & thin[e[:, 1]]]
    roots = union_find_roots(np.ascontiguousarray(e[:, 0]), np.ascontiguousarray(e[:, 1]), len(v))
    area = vertex_areas(v, f)
    tv = np.flatnonzero(thin)
    uniq, lab = np.unique(roots[tv], return_inverse=True)
    out = []
    order = np.argsort(lab, kind="stable")
    bounds = np.r_[0, np.cumsum(np.bincount(lab, minlength=uniq.size))]
    for c in range(uniq.size):
        vi = tv[order[bounds[c]:bounds[c + 1]]]
        a = float(area[vi].sum())
        if a < min_area or vi.size < min_vertices:
            continue
        k = vi[np.argmin(t[vi])]
        srt = vi[np.argsort(t[vi])]
        med = t[srt][min(np.searchsorted(np.cumsum(area[srt]), 0.5 * a), srt.size - 1)]
        out.append({"vertices": vi, "location": location(v[vi], area[vi]), "area_mm2": a,
                    "min_mm": float(t[k]), "median_mm": float(med), "min_location": location(v[k])})
    out.sort(key=lambda d: -d["area_mm2"])
    return out


def robust_min_wall(thickness: np.ndarray, regions: List[Dict], min_wall_mm: float) -> Optional[float]:
    """The part's thinnest wall, mm: the smallest thickness outside the isolated spots that
    :func:`thin_regions` leaves out (None when nothing was measured)."""
    t = np.asarray(thickness, np.float64).copy()
    spots = np.isfinite(t) & (t < min_wall_mm)
    for r in regions:
        spots[r["vertices"]] = False
    t[spots] = np.nan
    return float(np.nanmin(t)) if np.any(np.isfinite(t)) else None
