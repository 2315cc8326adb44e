"""How far thin material reaches beyond the body of a part that has the full wall thickness.

A part's *body* at wall ``w`` is its morphological opening by a ball of diameter ``w`` (Serra
1982, "Image Analysis and Mathematical Morphology"): the union of every ball of radius
``w / 2`` that fits inside. Material outside the body is thinner than ``w``. Where it reaches
only a little beyond the body it is the rim of a wedge or a rounded crease, which a printer
builds slightly blunted; where it reaches far it is a sheet, a fin or a rod that prints weak or
not at all. For a wedge of half-angle α the tip lies ``w/2 · (1/sin α − 1)`` beyond the body
(0.4 mm for α = 30° at w = 0.8 mm).

:func:`reach_beyond_body` measures, for surface points, the distance to the body: the distance
to the nearest centre of a ball of radius ``w / 2`` inside the part (a point at least ``w / 2``
from the surface), minus ``w / 2``. It searches along a cone of rays around the inward
direction, stepping along each ray by the distance deficit (sphere tracing, Hart 1996, "Sphere
tracing: a geometric method for the antialiased ray tracing of implicit surfaces"), so the
first point far enough from the surface is never stepped over.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.spatial import TriangleGrid
from ..model.errors import AnatomeshError

#: rings of the search cone and rays per ring; the axis itself is ray 0
_RINGS, _PER_RING = 3, 8
#: the cone's half-angle, degrees: wide enough to find the body beside a short lip
_HALF_ANGLE_DEG = 70.0
#: sphere-tracing steps per ray at most (each at least 2 % of the radius)
_MAX_STEPS = 60
#: a point this fraction of the radius along its inward direction must be inside (else: a fold)
_FOLD_STEP = 0.1



def cone_directions(axis: np.ndarray, half_angle_deg: float = _HALF_ANGLE_DEG, rings: int = _RINGS,
                    per_ring: int = _PER_RING) -> np.ndarray:
    """Unit directions (K, P, 3) around each unit ``axis`` (P, 3): the axis first, then ``rings``
    rings of ``per_ring`` directions tilted by up to ``half_angle_deg``, K = 1 + rings·per_ring."""
    u = np.asarray(axis, np.float64)
    u = u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    helper = np.where(np.abs(u[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(u, e1)
    out = [u]
    for r in range(1, rings + 1):
        th = np.radians(half_angle_deg) * r / rings
        for k in range(per_ring):
            ph = 2 * np.pi * (k + 0.5 * (r % 2)) / per_ring
            out.append(np.cos(th) * u + np.sin(th) * (np.cos(ph) * e1 + np.sin(ph) * e2))
    return np.stack(out)


def reach_beyond_body(grid: TriangleGrid, points: np.ndarray, inward: np.ndarray, wall: float,
                      limit: float) -> np.ndarray:
    """Distance (P,) mm from each surface point to the body of the part at wall ``wall`` mm (see
    the module docstring); ``inf`` where it is farther than ``limit`` mm (or not found).

    ``grid`` indexes the part's closed surface, ``points`` (P, 3) mm lie on it and ``inward``
    (P, 3) point into the solid (e.g. the mean of the faces' inward normals: the bisector at a
    crease). Rays of :func:`cone_directions` leave each point; along a ray the first point at
    least ``wall / 2`` from the surface, before the ray leaves the solid, is a ball centre of
    the body. The cone's rays sample the body near the point, so the result is an upper bound
    of the true distance (exact along the bisector of a symmetric wedge).

    ``NaN`` marks points whose inward direction leaves the solid at once (a fold of the
    surface, where the mean of the faces' normals does not point into the material): there the
    distance is not defined."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    if not (np.isfinite(wall) and wall > 0 and np.isfinite(limit) and limit >= 0):
        raise AnatomeshError(f"reach_beyond_body needs a positive wall and a limit in mm, got "
                             f"{wall}, {limit}")
    rho = 0.5 * float(wall)
    best = np.full(len(p), np.inf)
    if len(p) == 0:
        return best
    t_min = 1e-6 * max(float(np.ptp(grid.vertices, axis=0).max()), 1e-3)
    u = np.asarray(inward, np.float64).reshape(-1, 3)
    fold = ~grid.contains(p + _FOLD_STEP * rho * u)
    best[fold] = np.nan
    todo = np.flatnonzero(~fold)
    for w in cone_directions(u):
        if todo.size == 0:
            break
        found, dist = _trace(grid, p[todo], w[todo], rho, rho + float(limit), t_min)
        best[todo[found]] = dist[found]
        todo = todo[~found]
    return best


def reach_by_balls(points: np.ndarray, centres: np.ndarray, radii: np.ndarray, wall: float,
                   limit: float) -> np.ndarray:
    """Distance (P,) mm from each point to the union of the inscribed balls (centres (B, 3) mm,
    radii (B,) mm, e.g. the shrinking balls of :func:`.thickness.face_thickness`) at least
    ``wall / 2`` in radius: ``min(|p − c| − r)``, 0 inside one, ``inf`` beyond ``limit`` mm.

    Every such ball lies in the part's body at wall ``wall`` (it is a union of balls of
    diameter ``wall``), so this is an upper bound of the distance to the body, as close as the
    balls sample the medial axis (one per face): on a wedge of full angle θ the nearest ball
    from the tip is the one of radius ``wall / 2``, ``(wall/2)·(1/sin(θ/2) − 1)`` away, found to
    within the spacing of the faces' balls."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    c = np.asarray(centres, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).reshape(-1)
    keep = np.isfinite(r) & (r >= 0.5 * float(wall)) & np.all(np.isfinite(c), axis=1)
    c, r = c[keep], r[keep]
    out = np.full(len(p), np.inf)
    if len(p) == 0 or len(c) == 0:
        return out
    tree = cKDTree(c)
    for i, near in enumerate(tree.query_ball_point(p, float(limit) + float(r.max()))):
        if near:
            gap = np.linalg.norm(c[near] - p[i], axis=1) - r[near]
            out[i] = max(float(gap.min()), 0.0)
    out[out > limit] = np.inf
    return out


def _trace(grid: TriangleGrid, p: np.ndarray, w: np.ndarray, rho: float, s_max: float, t_min: float):
    """Sphere-trace rays ``p + s·w`` for the first s with distance to the surface ≥ ``rho``,
    before the ray leaves the solid and below ``s_max``. Returns (found (P,) bool, s − rho (P,))."""
    t_exit, _, _, _ = grid.cast(p, w, t_min=t_min)
    stop = np.minimum(t_exit, s_max)
    s = np.full(len(p), rho)
    found = np.zeros(len(p), bool)
    live = np.flatnonzero(s < stop)
    for _ in range(_MAX_STEPS):
        if live.size == 0:
            break
        c = p[live] + s[live, None] * w[live]
        d, _, _ = grid.closest(c, max_distance=rho)
        hit = ~(d < rho * (1.0 - 1e-6))
        if np.any(hit):  # a ray that left through a gap in the cone's reasoning: check inside
            h = live[hit]
            inside = grid.contains(p[h] + s[h, None] * w[h])
            found[h[inside]] = True
        step = np.maximum(rho - np.where(hit, rho, d), 0.02 * rho)
        s[live[~hit]] += step[~hit]
        live = live[~hit]
        live = live[s[live] < stop[live]]
    return found, s - rho
