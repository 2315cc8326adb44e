"""A uniform grid over the triangles of a mesh: closest-point queries, ray casting, inside tests.

Any stage that measures distances to a surface (print checks, smoothing and decimation error in
mm) can build one :class:`TriangleGrid` and query it many times. Triangles are binned by their
bounding boxes into cubic cells of side ``cell_size`` mm (default twice the mean edge length,
enlarged so that there are at most ~8 cells per triangle). Numba kernels, queries in parallel,
no allocation per query: one grid for every distance query in Anatomesh
(:mod:`anatomesh.core.geometry.measure` measures with it).

* :meth:`TriangleGrid.closest` — nearest surface point of each query point (Ericson 2004,
  "Real-Time Collision Detection", §5.1.5), searched ring by ring of cells with a distance bound.
* :meth:`TriangleGrid.cast` — first hit and number of crossings along rays, walking cells with
  Amanatides & Woo 1987 ("A fast voxel traversal algorithm") and testing triangles with Möller &
  Trumbore 1997 ("Fast, minimum storage ray-triangle intersection").
* :meth:`TriangleGrid.contains` — inside a closed surface by crossing parity (majority of three
  rays), independent of the faces' orientation.

Example
-------
>>> g = TriangleGrid(vertices, faces)
>>> dist, face, closest = g.closest(points, max_distance=5.0)
>>> inside = g.contains(points)
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from . import _spatial_kernels as _k
from ..model.errors import AnatomeshError
from .neighbors import check_faces

#: feature of the closest point on its triangle: vertex 0/1/2, edge 01/12/20, interior
FEATURE_VERTEX = (0, 1, 2)
FEATURE_EDGE = {3: (0, 1), 4: (1, 2), 5: (2, 0)}
FEATURE_INTERIOR = 6

# three fixed, "generic" directions for parity tests (not parallel to grid axes or voxel faces)
_PARITY_DIRS = np.array([[0.5773, 0.6009, 0.5528], [-0.7071, 0.3162, 0.6325],
                         [0.2182, -0.8729, 0.4364]])
_PARITY_DIRS /= np.linalg.norm(_PARITY_DIRS, axis=1, keepdims=True)


def _as_points(points, what="points") -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 1 and p.size == 3:
        p = p.reshape(1, 3)
    if p.ndim != 2 or p.shape[1] != 3:
        raise AnatomeshError(f"{what} must be an (N, 3) array of positions in mm, got shape {p.shape}")
    if p.size and not np.all(np.isfinite(p)):
        raise AnatomeshError(f"{what} contain NaN or infinite coordinates: clean the mesh first")
    return np.ascontiguousarray(p)


class TriangleGrid:
    """Uniform grid over a triangle mesh (vertices (N, 3) mm, faces (M, 3) int).

    Attributes
    ----------
    vertices : (N, 3) float64, faces : (M, 3) int32
    origin : (3,) float64 mm, cell_size : float mm, dims : (3,) int64
    start, items : cell → triangle CSR (int64 (C+1,), int32)
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, cell_size: Optional[float] = None,
                 max_cells_per_face: float = 8.0):
        self.vertices = _as_points(vertices, "vertices")
        self.faces = check_faces(faces, len(self.vertices))
        v, f = self.vertices, self.faces
        if f.shape[0] == 0:
            lo = np.zeros(3) if v.size == 0 else v.min(0)
            hi = lo
        else:
            used = v[f.ravel()]
            lo, hi = used.min(0), used.max(0)
        ext = np.maximum(hi - lo, 1e-9)
        if cell_size is None:
            if f.shape[0]:
                e = np.linalg.norm(v[f[:, 1]] - v[f[:, 0]], axis=1)
                cell_size = 2.0 * float(np.mean(e)) if e.size else 1.0
            else:
                cell_size = 1.0
            cell_size = max(cell_size, float(ext.max()) * 1e-6, 1e-9)
            max_cells = max(1000.0, max_cells_per_face * f.shape[0])
            while np.prod(np.floor(ext / cell_size) + 1) > max_cells:
                cell_size *= 1.25
        elif not cell_size > 0:
            raise AnatomeshError(f"cell_size must be positive, got {cell_size}")
        self.cell_size = float(cell_size)
        self.dims = (np.floor(ext / self.cell_size).astype(np.int64) + 1)
        self.origin = lo - 0.5 * (self.dims * self.cell_size - ext)  # centre the box
        self.start, self.items = _k.build_grid(v, f, self.origin, self.cell_size, self.dims)

    # -----------------------------------------------------------------------------------------
    def closest(self, points: np.ndarray, max_distance=np.inf, skip_faces: Optional[np.ndarray] = None,
                return_feature: bool = False):
        """Nearest surface point of each point, searching no farther than ``max_distance`` mm.

        The search visits cells ring by ring around the point, so its cost grows with
        (distance / cell_size)³: fine near the surface (smoothing error, gaps, thickness), slow
        for points far from every triangle — bound it with ``max_distance`` there.

        Parameters
        ----------
        points : (P, 3) mm
        max_distance : float or (P,) mm; points with nothing that near get distance inf, face -1
        skip_faces : (M,) bool, optional — faces ignored by the search
        return_feature : also return the feature code (:data:`FEATURE_VERTEX` 0–2,
            :data:`FEATURE_EDGE` 3–5, :data:`FEATURE_INTERIOR` 6) of each closest point

        Returns
        -------
        distance (P,) float64 mm, face (P,) int64, closest (P, 3) float64 mm [, feature (P,) int64]
        """
        p = _as_points(points)
        md = np.broadcast_to(np.asarray(max_distance, np.float64), (p.shape[0],)).copy()
        skip = np.zeros(0, np.bool_) if skip_faces is None else np.ascontiguousarray(skip_faces, np.bool_)
        if skip.size and skip.shape[0] != self.faces.shape[0]:
            raise AnatomeshError(f"skip_faces must have one flag per face ({self.faces.shape[0]}), "
                                 f"got {skip.shape[0]}")
        if p.shape[0] == 0 or self.faces.shape[0] == 0:
            n = p.shape[0]
            out = (np.full(n, np.inf), np.full(n, -1, np.int64), np.full((n, 3), np.nan))
            return out + (np.full(n, -1, np.int64),) if return_feature else out
        d, f, feat, q = _k.closest_points(p, self.vertices, self.faces, self.origin, self.cell_size,
                                          self.dims, self.start, self.items, md, skip)
        return (d, f, q, feat) if return_feature else (d, f, q)

    def cast(self, origins: np.ndarray, directions: np.ndarray, t_min: float = 0.0,
             t_max: float = np.inf, skip_vertex: Optional[np.ndarray] = None,
             count_all: bool = False, edge_tolerance: float = 1e-7):
        """Cast rays ``origin + t * direction`` (directions are normalised here).

        Parameters
        ----------
        origins, directions : (R, 3)
        t_min, t_max : hits with t in (t_min, t_max] mm count
        skip_vertex : (R,) int, optional — ignore the faces around this vertex (rays leaving a
            vertex of the mesh itself); -1 for none
        count_all : walk to the end and count every crossing (for parity); else stop at the first
        edge_tolerance : barycentric distance to an edge under which a hit is flagged ambiguous

        Returns
        -------
        t (R,) float64 mm (inf: no hit), face (R,) int64, crossings (R,) int64, ambiguous (R,) bool
        """
        o = _as_points(origins, "ray origins")
        d = _as_points(directions, "ray directions")
        if d.shape != o.shape:
            raise AnatomeshError(f"ray origins {o.shape} and directions {d.shape} must match")
        norm = np.linalg.norm(d, axis=1, keepdims=True)
        if np.any(norm == 0):
            raise AnatomeshError("ray directions must be non-zero")
        d = np.ascontiguousarray(d / norm)
        sv = np.zeros(0, np.int64) if skip_vertex is None else np.ascontiguousarray(skip_vertex, np.int64)
        if o.shape[0] == 0 or self.faces.shape[0] == 0:
            n = o.shape[0]
            return (np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros(n, np.int64),
                    np.zeros(n, bool))
        return _k.cast_rays(o, d, self.vertices, self.faces, self.origin, self.cell_size, self.dims,
                            self.start, self.items, float(t_min), float(t_max), sv,
                            bool(count_all), float(edge_tolerance))

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Exact distance (mm) from each point (P, 3) to the nearest triangle, (P,) float64."""
        return self.closest(_as_points(points))[0]

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Inside test (P,) bool for a closed surface: odd crossings along a ray, majority of
        three fixed directions (orientation of the faces does not matter)."""
        p = _as_points(points)
        votes = np.zeros(p.shape[0], np.int64)
        for d in _PARITY_DIRS:
            _, _, n, _ = self.cast(p, np.broadcast_to(d, p.shape), count_all=True)
            votes += n % 2
        return votes >= 2

    def shrinking_balls(self, points: np.ndarray, inward: np.ndarray, r0: np.ndarray, *,
                        min_sep_cos: float, max_iter: int = 40, tol: float = 1e-6):
        """Largest empty balls touching surface points, centres along the inward directions
        (shrinking ball, Ma, Bae & Kobbelt 2012, "3D medial axis point approximation using nearest
        neighbors and the normal field").

        ``points`` (P, 3) mm on the surface, ``inward`` (P, 3) unit directions, ``r0`` (P,) start
        radii mm. A nearest surface point seen from the centre within the separation angle
        (cos > ``min_sep_cos``) of the start belongs to the same side and stops the shrinking.
        Returns ``(radius (P,) mm, empty (P,) bool)``; empty: the final ball holds no surface."""
        return _k.shrinking_ball(_as_points(points), _as_points(inward, "inward"),
                                 np.ascontiguousarray(r0, np.float64), self.vertices, self.faces,
                                 self.origin, self.cell_size, self.dims, self.start, self.items,
                                 float(min_sep_cos), int(max_iter), float(tol))

    def ball_cover(self, centres: np.ndarray, radii: np.ndarray, pad: float, ids: np.ndarray,
                   out: np.ndarray) -> None:
        """For a grid over points (degenerate triangles (i, i, i)): raise ``out[ids[item]]`` to
        each ball's diameter for every point within radius + ``pad`` of its centre (Hildebrand &
        Rüegsegger 1997 local thickness). ``centres`` (B, 3) mm, ``radii`` (B,) mm, ``ids`` maps
        this grid's items to ``out``'s index, ``out`` float64 updated in place."""
        _k.cover_max(_as_points(centres, "centres"), np.ascontiguousarray(radii, np.float64),
                     float(pad), self.vertices, self.origin, self.cell_size, self.dims, self.start,
                     np.ascontiguousarray(ids, np.int32), out)


def point_triangle_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                            max_distance=np.inf) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-shot :meth:`TriangleGrid.closest` (builds the grid): (distance, face, closest point)."""
    return TriangleGrid(vertices, faces).closest(points, max_distance)
