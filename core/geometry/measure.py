"""What smoothing (or decimation) did to a surface, in millimetres.

Seed §6.5.4: judge a smoothed surface by its distance to the unsmoothed one (Hausdorff =
worst case, mean = typical), by its volume change and by its curvature; add triangle quality
and the topology guard. All functions take plain arrays (``vertices (N, 3)`` mm, ``faces (M, 3)``);
:func:`compare` bundles everything for one shell.

Distances are *exact* point-to-triangle distances (Ericson 2004) found through the uniform grid
of triangles of :mod:`anatomesh.core.geometry.spatial` (numba, parallel), but measured from sample points: the vertices plus the face
centroids of one surface to the triangles of the other, and the same the other way round. The
symmetric Hausdorff distance is the max of both directions over these samples, so it can
underestimate the true (continuous) Hausdorff distance by at most the distance a point moves
within a triangle between samples — a fraction of an edge length.
"""
from __future__ import annotations

from typing import Dict, Tuple

import numpy as np

from . import _measure_kernels as _k
from ..model.errors import AnatomeshError
from ..model.mesh import check_arrays, degenerate_faces, signed_volume, surface_area
from .topology import topology
from .neighbors import structure as _structure
from .spatial import TriangleGrid


# ---------------------------------------------------------------------------------------------
# distances
# ---------------------------------------------------------------------------------------------
def sample_points(vertices, faces) -> np.ndarray:
    """The vertices used by faces plus every face centroid, (P, 3) float64 mm."""
    v, f = check_arrays(vertices, faces)
    used = np.unique(f)
    return np.concatenate([v[used], v[f].mean(axis=1)])


def point_to_surface(points, vertices, faces) -> np.ndarray:
    """Exact distance (mm) from each point to the surface ``(vertices, faces)``, (P,) float64."""
    v, f = check_arrays(vertices, faces)
    if f.shape[0] == 0:
        raise AnatomeshError("cannot measure distances to a surface without triangles")
    return TriangleGrid(v, f).distance(points)


def surface_distance(a_vertices, a_faces, b_vertices, b_faces) -> Dict[str, float]:
    """Symmetric distances between two surfaces, sampled at vertices + face centroids.

    Returns ``{"hausdorff_mm", "mean_mm", "a_to_b_max_mm", "b_to_a_max_mm", "a_to_b_mean_mm",
    "b_to_a_mean_mm"}``; ``mean_mm`` averages all samples of both directions.
    """
    da = point_to_surface(sample_points(a_vertices, a_faces), b_vertices, b_faces)
    db = point_to_surface(sample_points(b_vertices, b_faces), a_vertices, a_faces)
    return {
        "hausdorff_mm": float(max(da.max(), db.max())),
        "mean_mm": float(np.concatenate([da, db]).mean()),
        "a_to_b_max_mm": float(da.max()), "b_to_a_max_mm": float(db.max()),
        "a_to_b_mean_mm": float(da.mean()), "b_to_a_mean_mm": float(db.mean()),
    }


# ---------------------------------------------------------------------------------------------
# volume, curvature, triangle quality
# ---------------------------------------------------------------------------------------------
def volume_change(before_vertices, after_vertices, faces) -> float:
    """Volume change in % of the closed surface ``faces`` moved from ``before`` to ``after``."""
    v0 = signed_volume(before_vertices, faces)
    v1 = signed_volume(after_vertices, faces)
    if v0 == 0:
        return 0.0 if v1 == 0 else float("inf")
    return 100.0 * (v1 - v0) / abs(v0)


def vertex_curvatures(vertices, faces) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete curvatures per vertex (Meyer, Desbrun, Schröder & Barr 2003).

    Returns
    -------
    mean : (N,) float64, 1/mm — from the cotangent Laplacian over the mixed Voronoi area,
        positive where the surface is convex (outward normals); 1/R on a sphere of radius R.
    gaussian : (N,) float64, 1/mm² — angle deficit ``(2π − Σθ) / A``; 1/R² on a sphere.
    area : (N,) float64, mm² — the mixed Voronoi area of each vertex (0 if unused).
    Values at open-boundary vertices are not meaningful.
    """
    v, f = check_arrays(vertices, faces)
    s = _structure(f, v.shape[0])
    H, K, A = np.zeros(len(v)), np.zeros(len(v)), np.zeros(len(v))
    _k.vertex_curvatures(v, s.faces, s.vf_offsets, s.vf, H, K, A)
    return H, K, A


def curvature_summary(vertices, faces) -> Dict[str, float]:
    """Area-weighted summary of |mean curvature| (1/mm) and |Gaussian curvature| (1/mm²).

    Smoothing lowers these (Bade et al. 2006, "Comparison of fundamental mesh smoothing
    algorithms for medical surface models"); compare a surface before and after.
    """
    H, K, A = vertex_curvatures(vertices, faces)
    used = A > 0
    if not np.any(used):
        return {"mean_abs_H": 0.0, "p95_abs_H": 0.0, "max_abs_H": 0.0, "mean_abs_K": 0.0}
    h, k, a = np.abs(H[used]), np.abs(K[used]), A[used]
    return {"mean_abs_H": float(np.sum(a * h) / a.sum()), "p95_abs_H": float(np.percentile(h, 95)),
            "max_abs_H": float(h.max()), "mean_abs_K": float(np.sum(a * k) / a.sum())}


def triangle_angles(vertices, faces) -> np.ndarray:
    """Interior angles in degrees, (M, 3) float64 (corner k at vertex ``faces[:, k]``)."""
    v, f = check_arrays(vertices, faces)
    out = np.empty((f.shape[0], 3))
    _k.triangle_angles(v, f, out)
    return np.degrees(out)


def triangle_quality(vertices, faces) -> Dict[str, float]:
    """Minimum-angle statistics (degrees): worst, 1st percentile, mean, share below 10°."""
    ang = triangle_angles(vertices, faces)
    if ang.size == 0:
        return {"min_angle_deg": 0.0, "p01_min_angle_deg": 0.0, "mean_min_angle_deg": 0.0,
                "fraction_below_10deg": 0.0}
    m = ang.min(axis=1)
    return {"min_angle_deg": float(m.min()), "p01_min_angle_deg": float(np.percentile(m, 1)),
            "mean_min_angle_deg": float(m.mean()), "fraction_below_10deg": float(np.mean(m < 10.0))}


def flipped_faces(before_vertices, after_vertices, faces) -> int:
    """Faces whose normal turned by more than 90° (folds created by smoothing)."""
    a, f = check_arrays(before_vertices, faces)
    b, _ = check_arrays(after_vertices, faces)

    def normals(v):
        return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])

    return int(np.count_nonzero(np.einsum("ij,ij->i", normals(a), normals(b)) < 0))


# ---------------------------------------------------------------------------------------------
# one shell, before and after
# ---------------------------------------------------------------------------------------------
_TOPO_KEYS = ("components", "genus", "closed", "manifold", "oriented", "degenerate_faces")


def compare(before_vertices, after_vertices, faces, *, distances: bool = True,
            curvature: bool = True) -> Dict:
    """Everything about one shell smoothed from ``before`` to ``after`` (same faces).

    Returns a JSON-ready dict: ``volume_before_mm3``, ``volume_after_mm3``, ``volume_change_pct``,
    ``area_before_mm2``, ``area_after_mm2``, ``max_displacement_mm`` (largest vertex move),
    ``hausdorff_mm`` and ``mean_distance_mm`` (symmetric, to the unsmoothed surface; with
    ``distances``), ``curvature_before``/``curvature_after`` (with ``curvature``),
    ``quality_after`` (min angles), ``flipped_faces``, ``topology_before``/``topology_after``
    (components, genus, closed, manifold, oriented, degenerate faces) and
    ``topology_changed``: the names of those fields that differ. ``before`` and ``after`` share
    their faces, so components, genus, closedness and orientation cannot change (they are
    computed once); degenerate (zero-area) faces and folds are what smoothing can add.
    """
    a, f = check_arrays(before_vertices, faces)
    b, _ = check_arrays(after_vertices, faces)
    if a.shape != b.shape:
        raise AnatomeshError(f"before and after must have the same vertices, got {a.shape} and {b.shape}")
    used = np.unique(f)
    vol0, vol1 = signed_volume(a, f), signed_volume(b, f)
    out: Dict = {
        "faces": int(f.shape[0]),
        "volume_before_mm3": vol0,
        "volume_after_mm3": vol1,
        "volume_change_pct": 100.0 * (vol1 - vol0) / abs(vol0) if vol0 else 0.0,
        "area_before_mm2": surface_area(a, f),
        "area_after_mm2": surface_area(b, f),
        "max_displacement_mm": float(np.linalg.norm(b[used] - a[used], axis=1).max()) if used.size else 0.0,
    }
    if distances and f.shape[0]:
        d = surface_distance(b, f, a, f)
        out["hausdorff_mm"] = d["hausdorff_mm"]
        out["mean_distance_mm"] = d["mean_mm"]
    if curvature and f.shape[0]:
        out["curvature_before"] = curvature_summary(a, f)
        out["curvature_after"] = curvature_summary(b, f)
    out["quality_after"] = triangle_quality(b, f)
    out["flipped_faces"] = flipped_faces(a, b, f)
    # connectivity is the same before and after, so only the geometric count can differ
    t0 = topology(a, f).as_dict()
    t1 = dict(t0, degenerate_faces=int(degenerate_faces(b, f).size))
    out["topology_before"] = {k: t0[k] for k in _TOPO_KEYS}
    out["topology_after"] = {k: t1[k] for k in _TOPO_KEYS}
    out["topology_changed"] = [k for k in _TOPO_KEYS if t0[k] != t1[k]]
    return out
