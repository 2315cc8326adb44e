"""3D-print readiness checks on all parts together (like Blender's 3D Print Toolbox, but across
parts, in mm, and independent of the normals' quality).

Each check is a small function returning offending element indices and values:

* solid: closed, 2-manifold, consistently oriented (:func:`anatomesh.core.model.mesh.topology`),
  :func:`self_intersections` and :func:`part_intersections` (Möller 1997, "A fast
  triangle-triangle intersection test", over a uniform grid), :func:`sliver_faces` (minimum angle),
  degenerate faces (:func:`anatomesh.core.model.mesh.degenerate_faces`), :func:`tiny_shells`;
* :func:`wall_thickness` per vertex: a ray cast inwards (inward chosen by crossing parity, not by
  the normals' sign) cross-checked with the shrinking-ball inscribed sphere (Ma, Bae & Kobbelt
  2012, "3D medial axis point approximation using nearest neighbors and the normal field");
  :func:`thin_regions` groups thin vertices into connected regions with location and area;
* :func:`part_gaps`: minimum distance between every pair of parts away from the seams they share
  (faces and vertices at identical positions are contact by design, not gaps).

:func:`check_parts` runs everything for a printer profile (:data:`PROFILES`) and returns the
report dict. Units are mm, mm², mm³ throughout.

Seams: label maps become surfaces where touching organs share interface faces. Vertices are
matched across parts by exact position ("welded"), so parts exported with their own copies of
the seam vertices are handled the same as parts sharing indices.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..geometry.kernels import union_find_roots
from ..model.errors import AnatomeshError
from ..geometry.topology import closed_and_oriented, component_measures, topology
from ..model.mesh import (Mesh, check_arrays, degenerate_faces, face_areas, vertex_areas,
                          vertex_normals, weld_ids)
from ..model.progress import Progress, report, sub
from ..geometry.intersections import crossing_pairs
from ..geometry.spatial import FEATURE_EDGE, TriangleGrid

#: printer profiles: minimum printable wall and minimum gap that stays open, mm
PROFILES: Dict[str, Dict[str, float]] = {
    "fdm": {"min_wall": 0.8, "min_gap": 0.5, "min_shell_mm3": 1.0},
    "resin": {"min_wall": 0.4, "min_gap": 0.2, "min_shell_mm3": 0.1},
}
#: pairs of parts closer than this are listed in the report, mm
GAP_REPORT_MM = 5.0
#: faces with an angle below this are slivers, degrees
SLIVER_ANGLE_DEG = 1.0
#: faces at most this large are degenerate, mm²
DEGENERATE_AREA_MM2 = 1e-10
_MAX_REGIONS = 50
#: a ball estimate below this fraction of the ray estimate is a collapsed ball at a sharp edge
_BALL_RAY_RATIO = 0.5
#: shrinking stops at a surface point seen from the ball's centre within ~100° of the start: it
#: is the vertex's own side (curvature, facets, a tilted normal), not the opposite wall
_SEPARATION_COS = -0.2
#: check_parts measures walls up to this thickness (at least 5 x min_wall), mm
_THICK_CAP_MM = 5.0
#: a vertex within this many mean edge lengths of an inscribed ball's sphere is reached by it
_COVER_PAD = 0.25


def resolve_profile(profile="fdm", min_wall: Optional[float] = None, min_gap: Optional[float] = None,
                    min_shell_mm3: Optional[float] = None) -> Dict[str, float]:
    """The profile's limits (a name in :data:`PROFILES` or a dict), with overrides applied."""
    if isinstance(profile, dict):
        base = dict(PROFILES["fdm"])
        base.update(profile)
        name = str(profile.get("name", "custom"))
    else:
        if profile not in PROFILES:
            raise AnatomeshError(f"unknown printer profile {profile!r}: use one of "
                                 f"{', '.join(sorted(PROFILES))} or pass min_wall/min_gap in mm")
        base = dict(PROFILES[profile])
        name = profile
    for key, val in (("min_wall", min_wall), ("min_gap", min_gap), ("min_shell_mm3", min_shell_mm3)):
        if val is not None:
            if not np.isfinite(val) or val < 0:
                raise AnatomeshError(f"{key} must be a non-negative number of mm, got {val}")
            base[key] = float(val)
    base["name"] = name
    return base


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------


def _location(points: np.ndarray, weights: Optional[np.ndarray] = None) -> List[float]:
    p = np.asarray(points, np.float64).reshape(-1, 3)
    if weights is None or not np.sum(weights) > 0:
        return [round(float(x), 3) for x in p.mean(0)]
    return [round(float(x), 3) for x in np.average(p, axis=0, weights=weights)]


# ---------------------------------------------------------------------------------------------
# solid checks
# ---------------------------------------------------------------------------------------------
def sliver_faces(vertices: np.ndarray, faces: np.ndarray, min_angle_deg: float = SLIVER_ANGLE_DEG):
    """Faces whose smallest angle is below ``min_angle_deg``: (indices (K,) int64, angles (K,) deg).

    Degenerate faces (zero area) have angle 0 and are included."""
    v, f = check_arrays(vertices, faces)
    if f.shape[0] == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    p = v[f]
    ang = np.empty((f.shape[0], 3))
    for k in range(3):
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        cr = np.linalg.norm(np.cross(a, b), axis=1)
        ang[:, k] = np.degrees(np.arctan2(cr, np.einsum("ij,ij->i", a, b)))
    amin = ang.min(1)
    idx = np.flatnonzero(~(amin >= min_angle_deg))
    return idx, amin[idx]


def tiny_shells(vertices: np.ndarray, faces: np.ndarray, min_volume_mm3: float) -> List[Dict]:
    """Connected components enclosing less than ``min_volume_mm3`` (absolute volume).

    Returns ``[{"faces": index array, "volume_mm3", "area_mm2", "location"}]``, smallest first;
    uses :func:`anatomesh.core.model.mesh.component_measures`."""
    v, f = check_arrays(vertices, faces)
    out = []
    if f.shape[0] == 0:
        return out
    for comp in component_measures(v, f):
        vol = abs(comp["volume_mm3"])
        if vol < min_volume_mm3:
            loc = _location(v[f[comp["faces"]].ravel()])
            out.append({"faces": comp["faces"], "volume_mm3": vol, "area_mm2": comp["area_mm2"],
                        "location": loc})
    out.sort(key=lambda d: d["volume_mm3"])
    return out


def part_intersections(meshes: Sequence[Mesh]) -> List[Dict]:
    """Pairs of parts whose faces cross (shared seams excepted).

    Returns ``[{"a", "b" (names), "faces_a", "faces_b" (index arrays), "location"}]``."""
    parts = [check_arrays(m.vertices, m.faces) for m in meshes]
    return _split_intersections(meshes, *crossing_pairs(parts))[1]


def _split_intersections(meshes, v, f, part, offs_f, pairs):
    """Self-intersecting face pairs per part, and crossing pairs of parts."""
    self_pairs = [np.zeros((0, 2), np.int64) for _ in meshes]
    cross = []
    if pairs.shape[0] == 0:
        return self_pairs, cross
    pa, pb = part[pairs[:, 0]], part[pairs[:, 1]]
    same = pa == pb
    for i in np.unique(pa[same]):
        sel = pairs[same & (pa == i)]
        self_pairs[i] = sel - offs_f[i]
    diff = ~same
    if np.any(diff):
        a = np.minimum(pa[diff], pb[diff])
        b = np.maximum(pa[diff], pb[diff])
        fa = np.where(pa[diff] == a, pairs[diff, 0], pairs[diff, 1])
        fb = np.where(pa[diff] == a, pairs[diff, 1], pairs[diff, 0])
        keys = a * len(meshes) + b
        for k in np.unique(keys):
            sel = keys == k
            i, j = int(k // len(meshes)), int(k % len(meshes))
            faces_all = np.r_[fa[sel], fb[sel]]
            cross.append({"a": meshes[i].name or str(i), "b": meshes[j].name or str(j),
                          "ia": i, "ib": j,
                          "faces_a": np.unique(fa[sel]) - offs_f[i],
                          "faces_b": np.unique(fb[sel]) - offs_f[j],
                          "location": _location(v[f[faces_all].ravel()])})
    return self_pairs, cross


# ---------------------------------------------------------------------------------------------
# wall thickness
# ---------------------------------------------------------------------------------------------
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
    from ..geometry.topology import face_components

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
    :func:`anatomesh.core.model.mesh.topology`) one parity ray per connected component tells whether
    that component's normals point out or in, and each face then needs only its first hit; on
    any other surface every face decides its inward side by parity itself.

    Face centroids are used rather than vertices because a face's normal is exact while a
    vertex normal at a crease or a staircase step is an average that sends rays across corners.
    ``max_thickness`` (mm) bounds the rays and the ball search (its cost grows with the cube of
    the radius): thicker walls come out as ``max_thickness``. With ``return_details`` also returns
    ``{"ray", "ball" (M,) mm, "decided" (M,) bool}`` (decided False: parity could not tell the
    inside, e.g. on an open surface).
    """
    v, f = check_arrays(vertices, faces)
    m = f.shape[0]
    out = np.full(m, np.nan)
    details = {"ray": np.full(m, np.nan), "ball": np.full(m, np.nan), "decided": np.zeros(m, bool),
               "centre": np.full((m, 3), np.nan), "inscribed": np.zeros(m, bool)}
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
                 min_vertices: int = 3) -> List[Dict]:
    """Connected regions of vertices thinner than ``min_wall`` mm (linked by mesh edges).

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
        out.append({"vertices": vi, "location": _location(v[vi], area[vi]), "area_mm2": a,
                    "min_mm": float(t[k]), "median_mm": float(med), "min_location": _location(v[k])})
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


# ---------------------------------------------------------------------------------------------
# gaps between parts
# ---------------------------------------------------------------------------------------------
def _row_keys(rows: np.ndarray) -> np.ndarray:
    """One comparable value per (K, 3) int64 row (exact, no overflow)."""
    r = np.ascontiguousarray(rows, np.int64)
    return r.view(np.dtype((np.void, 24))).ravel()


def _one_way_gap(va, na, skip_a, grid_b, fb, wb_shared_with_a, seam_b, max_d, min_cos):
    """Closest valid distance from A's vertices to B's surface: (dist, point on A, point on B)."""
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
    # a closest point on the seam (a shared vertex, or an edge between shared vertices) means A
    # reaches B through the seam itself: contact by design, not a gap
    fv = fb[np.maximum(face, 0)]
    for code in (0, 1, 2):
        m = ok & (feat == code)
        ok[m] = ~wb_shared_with_a[fv[m, code]]
    for code, (i, j) in FEATURE_EDGE.items():
        m = ok & (feat == code)
        ok[m] = ~(wb_shared_with_a[fv[m, i]] & wb_shared_with_a[fv[m, j]])
    # the closest pair must face each other (not run along either surface)
    u = q - va[pts]
    ln = np.linalg.norm(u, axis=1)
    has = ok & (ln > 0)
    vb = grid_b.vertices
    fn = np.cross(vb[fv[:, 1]] - vb[fv[:, 0]], vb[fv[:, 2]] - vb[fv[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    un = u / np.maximum(ln, 1e-300)[:, None]
    ca = np.abs(np.einsum("ij,ij->i", un, na[pts]))
    cb = np.abs(np.einsum("ij,ij->i", un, fn))
    ok[has] = (ca[has] >= min_cos) & (cb[has] >= min_cos)
    if not np.any(ok):
        return np.inf, None, None
    k = np.flatnonzero(ok)[np.argmin(d[ok])]
    return float(d[k]), va[pts[k]], q[k]


def _seam_index(parts, wids, nw):
    """Per part: the welded vertex ids it shares with other parts (sorted), and its faces that
    other parts have too (face indices, and one comparable key per such face)."""
    k = len(parts)
    seen = np.zeros(nw, np.int64)
    uw = [np.unique(wids[i][f.ravel()]) if len(f) else np.zeros(0, np.int64)
          for i, (_, f) in enumerate(parts)]
    for u in uw:
        seen[u] += 1
    multi = seen > 1
    seam_v = [u[multi[u]] for u in uw]
    seam_f, seam_key = [], []
    for i, (_, f) in enumerate(parts):
        if not len(f):
            seam_f.append(np.zeros(0, np.int64))
            seam_key.append(_row_keys(np.zeros((0, 3), np.int64)))
            continue
        wf = wids[i][f]
        cand = np.flatnonzero(np.all(multi[wf], axis=1))  # every corner shared: may be a seam face
        seam_f.append(cand)
        seam_key.append(_row_keys(np.sort(wf[cand], axis=1)))
    return seam_v, seam_f, seam_key


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
    k = len(parts)
    if grids is None:
        grids = [TriangleGrid(v, f) if len(f) else None for v, f in parts]
    boxes = []
    for v, f in parts:
        u = v[np.unique(f.ravel())] if len(f) else np.zeros((0, 3))
        boxes.append((u.min(0), u.max(0)) if len(u) else None)
    # weld all vertices; which welded ids each part uses
    allv = np.concatenate([v for v, _ in parts]) if k else np.zeros((0, 3))
    wid = weld_ids(allv)
    offs = np.cumsum([0] + [len(v) for v, _ in parts])
    wids = [wid[offs[i]:offs[i + 1]] for i in range(k)]
    normals = [vertex_normals(v, f) if len(f) else np.zeros_like(v) for v, f in parts]
    nw = int(wid.max()) + 1 if wid.size else 1
    seam_v, seam_f, seam_fkey = _seam_index(parts, wids, nw)
    flag = np.zeros(nw, bool)  # scratch: the welded ids a pair shares
    out = []
    cand = []
    for i in range(k):
        for j in range(i + 1, k):
            if boxes[i] is None or boxes[j] is None:
                continue
            sep = np.maximum(boxes[i][0] - boxes[j][1], boxes[j][0] - boxes[i][1])
            if np.linalg.norm(np.maximum(sep, 0)) <= max_distance:
                cand.append((i, j))
    for c, (i, j) in enumerate(cand):
        report(progress, c / max(len(cand), 1), f"gaps {names[i]}–{names[j]}")
        shared_ids = np.intersect1d(seam_v[i], seam_v[j], assume_unique=True)
        touching = bool(shared_ids.size)
        seam_area = 0.0
        seam_i = seam_j = None
        seam_loc = None
        flag[shared_ids] = True
        if touching:
            seam_i = np.zeros(len(parts[i][1]), bool)
            seam_j = np.zeros(len(parts[j][1]), bool)
            seam_i[seam_f[i][np.isin(seam_fkey[i], seam_fkey[j])]] = True
            seam_j[seam_f[j][np.isin(seam_fkey[j], seam_fkey[i])]] = True
            vi, fi = parts[i]
            if np.any(seam_i):
                seam_area = float(face_areas(vi, fi[seam_i]).sum())
                seam_loc = _location(vi[fi[seam_i]].reshape(-1, 3))
            else:
                seam_loc = _location(vi[flag[wids[i]]])
        best = (np.inf, None, None)
        for a, b, seam_b in ((i, j, seam_j), (j, i, seam_i)):
            va, fa_ = parts[a]
            fb = parts[b][1]
            r = _one_way_gap(va, normals[a], flag[wids[a]], grids[b], fb, flag[wids[b]],
                             seam_b, max_distance, min_cos)
            if r[0] < best[0]:
                best = r
        flag[shared_ids] = False
        if not touching and not np.isfinite(best[0]):
            continue
        clearance = best[0] if np.isfinite(best[0]) else None
        if touching:
            loc = seam_loc
        else:
            loc = _location(0.5 * (best[1] + best[2]))
        entry = {"a": names[i], "b": names[j], "ia": i, "ib": j, "touching": touching,
                 "seam_area_mm2": seam_area,
                 "min_gap_mm": 0.0 if touching else float(best[0]),
                 "clearance_mm": None if clearance is None else float(clearance),
                 "location": loc,
                 # parts sharing a seam print joined anyway (separate them with
                 # printfix.separate_parts): only a gap between parts apart fuses them
                 "fuses": (not touching) and clearance is not None and clearance < min_gap}
        if clearance is not None and touching:
            entry["clearance_location"] = _location(0.5 * (best[1] + best[2]))
        out.append(entry)
    report(progress, 1.0, "gaps done")
    out.sort(key=lambda d: (d["min_gap_mm"], d["clearance_mm"] if d["clearance_mm"] is not None else np.inf))
    return out


# ---------------------------------------------------------------------------------------------
# the report
# ---------------------------------------------------------------------------------------------
def _round(x, nd=3):
    return None if x is None or not np.isfinite(x) else round(float(x), nd)


def check_parts(meshes: Sequence[Mesh], profile="fdm", min_wall: Optional[float] = None,
                min_gap: Optional[float] = None, progress: Optional[Progress] = None) -> Dict:
    """Run every print check on all parts together; returns the report dict.

    Parameters
    ----------
    meshes : sequence of :class:`~anatomesh.core.model.mesh.Mesh` (vertices mm)
    profile : "fdm" | "resin" | dict (see :data:`PROFILES`); ``min_wall``/``min_gap`` override it

    Returns
    -------
    dict with ``profile`` (limits used), ``parts`` (one dict per mesh: name, closed, manifold,
    oriented, self_intersections, degenerate_faces, sliver_faces, tiny_shells, min_wall_mm,
    thin_area_mm2, thin_regions [{location, area_mm2, min_mm}], passed), ``intersections``
    (pairs of parts crossing), ``gaps`` (pairs closer than :data:`GAP_REPORT_MM`: a, b, touching,
    seam_area_mm2, min_gap_mm, clearance_mm, location, fuses) and ``passed``.
    """
    prof = resolve_profile(profile, min_wall, min_gap)
    meshes = list(meshes)
    for i, m in enumerate(meshes):
        if not isinstance(m, Mesh):
            raise AnatomeshError(f"check_parts takes Mesh objects; item {i} is {type(m).__name__}")
    parts = [check_arrays(m.vertices, m.faces) for m in meshes]
    names = [m.name or str(i) for i, m in enumerate(meshes)]
    report(progress, 0.0, "intersections")
    self_pairs, cross = _split_intersections(meshes, *crossing_pairs(parts))
    report(progress, 0.15, "parts")
    grids = []
    out_parts = []
    sp = sub(progress, 0.15, 0.8)
    near_seam = seam_neighbourhoods(parts)
    for i, ((v, f), name) in enumerate(zip(parts, names)):
        report(sp, i / max(len(parts), 1), f"wall thickness {name}")
        grids.append(TriangleGrid(v, f) if len(f) else None)
        out_parts.append(_check_one(v, f, name, grids[-1], prof, self_pairs[i], near_seam[i]))
    gaps = part_gaps(meshes, GAP_REPORT_MM, prof["min_gap"], grids=grids,
                     progress=sub(progress, 0.8, 1.0))
    inter = []
    for c in cross:
        inter.append({"a": c["a"], "b": c["b"], "faces_a": int(c["faces_a"].size),
                      "faces_b": int(c["faces_b"].size), "location": c["location"]})
        out_parts[c["ia"]]["part_intersections"] += 1
        out_parts[c["ib"]]["part_intersections"] += 1
        out_parts[c["ia"]]["passed"] = out_parts[c["ib"]]["passed"] = False
    known = {(g["ia"], g["ib"]) for g in gaps}
    for c in cross:  # crossing parts are at gap 0 even if the gap search saw nothing
        if (c["ia"], c["ib"]) not in known:
            gaps.append({"a": c["a"], "b": c["b"], "ia": c["ia"], "ib": c["ib"], "touching": False,
                         "seam_area_mm2": 0.0, "min_gap_mm": 0.0, "clearance_mm": 0.0,
                         "location": c["location"], "fuses": True})
        else:
            for g in gaps:
                if (g["ia"], g["ib"]) == (c["ia"], c["ib"]):
                    g["fuses"] = True
                    g["intersecting"] = True
    for g in gaps:
        g["min_gap_mm"] = _round(g["min_gap_mm"])
        g["clearance_mm"] = _round(g["clearance_mm"])
        g.setdefault("intersecting", False)
    passed = all(p["passed"] for p in out_parts) and not inter and not any(g["fuses"] for g in gaps)
    report(progress, 1.0, "print checks done")
    return {"profile": prof, "parts": out_parts, "intersections": inter, "gaps": gaps,
            "passed": bool(passed)}


def seam_neighbourhoods(parts: Sequence[Tuple[np.ndarray, np.ndarray]]) -> List[np.ndarray]:
    """Per part a bool mask (N,) of the vertices on a seam — a position another part has too —
    or sharing a face with one: where touching parts printed together back each other up."""
    if not parts:
        return []
    sizes = [len(v) for v, _ in parts]
    wid = weld_ids(np.concatenate([v for v, _ in parts]))
    owner = np.repeat(np.arange(len(parts)), sizes)
    users = np.bincount(np.unique(np.stack([wid, owner], 1), axis=0)[:, 0], minlength=int(wid.max()) + 1)
    shared = users[wid] > 1
    out, start = [], 0
    for (v, f), n in zip(parts, sizes):
        seam = shared[start:start + n]
        near = seam.copy()
        if len(f):
            near[f[seam[f].any(axis=1)].ravel()] = True
        out.append(near)
        start += n
    return out


def _check_one(v, f, name, grid, prof, self_pairs, near_seam=None) -> Dict:
    """Checks of one part (the per-part entry of the report).

    Thin regions lying wholly on or next to a seam with another part (``near_seam``) — the
    creases where smoothed neighbours meet — are backed by that neighbour when the parts print
    together: they are listed with ``seam_backed`` but do not fail the part (separate the parts,
    e.g. ``--clearance``, and they count)."""
    if f.shape[0] == 0:
        return {"name": name, "closed": False, "manifold": True, "oriented": True, "faces": 0,
                "self_intersections": 0, "degenerate_faces": 0, "sliver_faces": 0,
                "tiny_shells": [], "min_wall_mm": None, "thin_area_mm2": 0.0, "thin_regions": [],
                "part_intersections": 0, "passed": False}
    topo = topology(v, f)
    deg = degenerate_faces(v, f, DEGENERATE_AREA_MM2)
    sliv, _ = sliver_faces(v, f)
    shells = tiny_shells(v, f, prof["min_shell_mm3"])
    thick = wall_thickness(v, f, grid=grid, max_thickness=max(_THICK_CAP_MM, 5 * prof["min_wall"]),
                           oriented=bool(topo.closed and topo.manifold and topo.oriented))
    regions = thin_regions(v, f, thick, prof["min_wall"])
    for r in regions:
        r["seam_backed"] = bool(near_seam is not None and near_seam[r["vertices"]].all())
    free = [r for r in regions if not r["seam_backed"]]
    n_self = int(np.unique(self_pairs.ravel()).size)
    entry = {
        "name": name, "faces": int(f.shape[0]), "closed": bool(topo.closed),
        "manifold": bool(topo.manifold), "oriented": bool(topo.oriented),
        "components": int(topo.components), "genus": topo.genus,
        "self_intersections": n_self, "degenerate_faces": int(deg.size),
        "sliver_faces": int(sliv.size),
        "tiny_shells": [{"volume_mm3": round(s["volume_mm3"], 4), "faces": int(s["faces"].size),
                         "location": s["location"]} for s in shells],
        "min_wall_mm": _round(robust_min_wall(thick, free, prof["min_wall"])),
        "thin_area_mm2": round(float(sum(r["area_mm2"] for r in free)), 3),
        "seam_backed_thin_area_mm2": round(float(sum(r["area_mm2"] for r in regions if r["seam_backed"])), 3),
        "thin_regions": [{"location": r["location"], "area_mm2": round(r["area_mm2"], 3),
                          "min_mm": round(r["min_mm"], 3), "median_mm": round(r["median_mm"], 3),
                          "min_location": r["min_location"], "vertices": int(r["vertices"].size),
                          "seam_backed": r["seam_backed"]}
                         for r in (free + [r for r in regions if r["seam_backed"]])[:_MAX_REGIONS]],
        "thin_region_count": len(free),
        "part_intersections": 0,
    }
    entry["passed"] = bool(topo.closed and topo.manifold and topo.oriented and n_self == 0
                           and deg.size == 0 and not shells and not free)
    return entry


# ---------------------------------------------------------------------------------------------
# fixes
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# files → meshes → report
# ---------------------------------------------------------------------------------------------


