"""Precise isosurfaces: marching-cubes triangles refined onto the trilinear interpolant.

Marching cubes puts each vertex on a cell edge, where the trilinear interpolant of the samples
is linear, so the vertices lie on its level set; the flat triangles between them do not — inside
a cell the trilinear isosurface is curved, and at saddles and thin features a triangle can cut
well across it. :func:`refine` follows Allamandri, Cignoni, Montani and Scopigno 1998
("Adaptively adjusting marching cubes output to fit a trilinear reconstruction filter"): from each
triangle's centroid, Newton steps along the gradient find the nearest point of the trilinear
level set; where it is farther than ``tolerance`` mm from the flat estimate, the triangle is split
into three at that point (which keeps the surface closed and every edge shared by two triangles).

The result reports what it did and cost: triangles split, how far the surface moved (max / mean
distance of the new vertices from the flat triangles, mm) and seconds.
"""
from __future__ import annotations

import time
from typing import Dict, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.volume import Volume, convert_affine
from . import _precise_kernels as K

#: default tolerance as a fraction of the smallest voxel spacing
TOLERANCE_VOXELS = 0.02
#: Newton steps may go at most this far (voxels) from the centroid
MAX_STEP_VOXELS = 1.0


def refine(mesh: Mesh, volume: Volume, level: Optional[float] = None,
           tolerance: Optional[float] = None) -> Tuple[Mesh, Dict]:
    """The isosurface ``mesh`` of ``volume`` at ``level`` (default ``mesh.value``) with its
    triangles split onto the trilinear interpolant where they stray from it (module docstring).

    Parameters
    ----------
    mesh : Mesh
        Vertices (N, 3) mm in ``mesh.space``, as :func:`~anatomesh.core.extract.isosurface.isosurface`
        made them from ``volume``.
    tolerance : float, optional
        mm; triangles whose centroid is farther than this from the trilinear surface are split.
        Default :data:`TOLERANCE_VOXELS` x the smallest spacing.

    Returns
    -------
    (Mesh, info)
        A new Mesh (normals of the new vertices from the interpolant's gradient; ``meta`` kept,
        ``meta["precise"]`` = info) and ``info``: ``faces_before``, ``faces_after``,
        ``split_faces``, ``max_moved_mm``, ``mean_moved_mm`` (over the split faces),
        ``mean_moved_all_mm`` (over all faces), ``tolerance_mm``, ``seconds``.
    """
    t0 = time.perf_counter()
    level = mesh.value if level is None else level
    if level is None or not np.isfinite(float(level)):
        raise AnatomeshError("precise extraction needs the isovalue of the surface")
    data = np.asarray(volume.data)
    if data.dtype.kind not in "iuf" or min(data.shape) < 2:
        raise AnatomeshError("precise extraction needs a scalar volume of at least 2 voxels per axis")
    affine = convert_affine(volume.affine, volume.space, mesh.space)
    tol = TOLERANCE_VOXELS * min(volume.spacing) if tolerance is None else float(tolerance)
    if not tol > 0:
        raise AnatomeshError(f"precise extraction tolerance must be > 0 mm, got {tolerance!r}")
    info = {"faces_before": mesh.n_faces, "tolerance_mm": round(tol, 5)}
    if mesh.n_faces == 0:
        return mesh, dict(info, faces_after=0, split_faces=0, max_moved_mm=0.0, mean_moved_mm=0.0,
                          mean_moved_all_mm=0.0, seconds=0.0)
    inv = np.linalg.inv(affine)
    v_idx = mesh.vertices.astype(np.float64) @ inv[:3, :3].T + inv[:3, 3]
    centroids = np.ascontiguousarray(v_idx[mesh.faces].mean(axis=1))
    points = np.empty_like(centroids)
    grads = np.empty_like(centroids)
    ok = np.zeros(len(centroids), np.bool_)
    K.project(data, centroids, float(level), MAX_STEP_VOXELS, 1e-4, points, grads, ok)
    moved = np.linalg.norm((points - centroids) @ affine[:3, :3].T, axis=1)
    split = ok & (moved > tol)
    out = _split(mesh, split, points[split] @ affine[:3, :3].T + affine[:3, 3],
                 _normals(grads[split], affine))
    info.update(faces_after=out.n_faces, split_faces=int(split.sum()),
                max_moved_mm=round(float(moved[split].max()) if split.any() else 0.0, 5),
                mean_moved_mm=round(float(moved[split].mean()) if split.any() else 0.0, 5),
                mean_moved_all_mm=round(float(np.where(ok, moved, 0.0).mean()), 5),
                seconds=round(time.perf_counter() - t0, 4))
    out.meta["precise"] = info
    return out, info


def _split(mesh: Mesh, split: np.ndarray, new_vertices: np.ndarray, new_normals) -> Mesh:
    """Each face flagged in ``split`` replaced by three around its new vertex (same winding)."""
    f = mesh.faces
    ids = mesh.n_vertices + np.arange(int(split.sum()), dtype=np.int64)
    a, b, c = (f[split, k].astype(np.int64) for k in range(3))
    fans = np.stack([np.stack([a, b, ids], 1), np.stack([b, c, ids], 1), np.stack([c, a, ids], 1)], 1)
    faces = np.concatenate([f[~split], fans.reshape(-1, 3)])
    vertices = np.concatenate([mesh.vertices, new_vertices.astype(np.float32)])
    normals = None
    if mesh.normals is not None:
        normals = np.concatenate([mesh.normals, new_normals.astype(np.float32)])
    return Mesh(vertices, faces, normals, name=mesh.name, value=mesh.value, color=mesh.color,
                space=mesh.space, meta=dict(mesh.meta), vertex_colors=None)


def _normals(grads: np.ndarray, affine: np.ndarray) -> np.ndarray:
    """Unit normals (P, 3) from index-space gradients (P, 3): minus the gradient, mapped to mm
    by the inverse transpose of the affine (pointing out of the region above the level)."""
    n = -grads @ np.linalg.inv(affine[:3, :3])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)
