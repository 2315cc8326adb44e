"""Triangle meshes and the invariants every stage checks (one place for all of them).

A :class:`Mesh` is an indexed face set: shared vertices ``(N, 3) float32`` in mm and triangles
``(M, 3) int32``, counter-clockwise seen from outside (normals point out of the solid). Functions
here are pure numpy: edge lists are sorted once with ``np.unique``-style keys, which is fast enough
for a few million triangles and easy to read.

Topology: for a closed 2-manifold with ``C`` components, Euler characteristic
``χ = V − E + F`` and genus ``g = (2C − χ) / 2`` (a sphere has χ = 2, g = 0; a torus χ = 0, g = 1).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional, Tuple

import numpy as np

from .errors import AnatomeshError


@dataclass
class Mesh:
    """One surface: vertices (N, 3) float32 mm, faces (M, 3) int32, optional per-vertex normals.

    ``value`` is the label value (label maps) or the isovalue (scalar scans); ``space`` is
    ``"RAS"`` or ``"LPS"`` — the space the vertices are in. ``vertex_colors`` (N, 3) or (N, 4)
    float32 sRGB in [0, 1], optional: a colour per vertex (a distance or difference map) that the
    PLY and GLB writers and the Blender scene carry.
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: Optional[np.ndarray] = None
    name: str = ""
    value: Optional[float] = None
    color: Tuple[float, float, float] = (0.8, 0.8, 0.8)
    space: str = "RAS"
    meta: Dict = field(default_factory=dict)
    vertex_colors: Optional[np.ndarray] = None

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float32).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int32).reshape(-1, 3)
        if self.normals is not None:
            self.normals = np.ascontiguousarray(self.normals, dtype=np.float32).reshape(-1, 3)
        if self.vertex_colors is not None:
            c = np.ascontiguousarray(self.vertex_colors, dtype=np.float32)
            if c.ndim != 2 or c.shape[0] != len(self.vertices) or c.shape[1] not in (3, 4):
                raise AnatomeshError(f"vertex_colors must be ({len(self.vertices)}, 3 or 4) sRGB "
                                     f"values in [0, 1], got shape {c.shape}")
            self.vertex_colors = np.clip(c, 0.0, 1.0)

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])


# ---------------------------------------------------------------------------------------------
# edges
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# measures
# ---------------------------------------------------------------------------------------------
def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of each triangle in mm², float64 (M,)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return np.zeros(0)
    c = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return 0.5 * np.linalg.norm(c, axis=1)


def surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Total area in mm²."""
    return float(face_areas(vertices, faces).sum())


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Enclosed volume in mm³ by the divergence theorem; positive when faces are outward.

    Exact for closed meshes. Vertices are centred first so large patient coordinates lose no
    precision.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return 0.0
    v = v - v[f[0, 0]]
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def degenerate_faces(vertices: np.ndarray, faces: np.ndarray, min_area: float = 0.0) -> np.ndarray:
    """Indices of faces with a repeated vertex index or area <= ``min_area`` (mm²)."""
    f = np.asarray(faces)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    return np.flatnonzero(repeated | (face_areas(vertices, faces) <= min_area))


def duplicate_vertices(vertices: np.ndarray, faces: Optional[np.ndarray] = None) -> np.ndarray:
    """Indices of vertices at exactly the same position as an earlier (used) vertex."""
    v = np.ascontiguousarray(vertices)
    idx = np.arange(len(v))
    if faces is not None:
        idx = np.unique(np.asarray(faces).ravel())
    if idx.size == 0:
        return idx
    _, first, counts = np.unique(v[idx], axis=0, return_index=True, return_counts=True)
    mask = np.ones(idx.size, bool)
    mask[first] = False
    return idx[mask]


# ---------------------------------------------------------------------------------------------
# components and topology
# ---------------------------------------------------------------------------------------------


def compact(vertices: np.ndarray, faces: np.ndarray, normals: Optional[np.ndarray] = None):
    """Drop unused vertices; returns (vertices, faces, normals, old_index_of_each_new_vertex)."""
    f = np.asarray(faces, dtype=np.int64)
    used = np.unique(f.ravel())
    remap = np.full(len(vertices), -1, np.int64)
    remap[used] = np.arange(used.size)
    nf = remap[f].astype(np.int32)
    nn = None if normals is None else np.asarray(normals)[used]
    return np.asarray(vertices)[used], nf, nn, used


def check_arrays(vertices, faces) -> Tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise AnatomeshError(f"vertices must be an (N, 3) array in mm, got shape {v.shape}")
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3:
        raise AnatomeshError(f"faces must be an (M, 3) integer array, got shape {f.shape}")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise AnatomeshError(f"faces refer to vertex {int(f.max())} but the mesh has {len(v)} "
                             f"vertices: pass the matching vertex array")
    if not np.all(np.isfinite(v)):
        raise AnatomeshError("vertices contain NaN or infinite coordinates: the mesh is corrupt")
    return np.ascontiguousarray(v), np.ascontiguousarray(f, dtype=np.int32)


def weld_ids(vertices: np.ndarray) -> np.ndarray:
    """An id (N,) int64 per vertex, equal for vertices at exactly the same position."""
    v = np.asarray(vertices)
    if len(v) == 0:
        return np.zeros(0, np.int64)
    order = np.lexsort((v[:, 2], v[:, 1], v[:, 0]))
    vs = v[order]
    new = np.r_[True, np.any(vs[1:] != vs[:-1], axis=1)]
    ids = np.empty(len(v), np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids


def row_keys(rows: np.ndarray) -> np.ndarray:
    """One comparable value per row of a (K, C) integer array: (K,) void keys, equal exactly when
    the rows are equal (for ``np.unique``, ``np.isin``, sorting; no arithmetic, so no overflow).
    The rows are read as int64."""
    r = np.ascontiguousarray(rows, np.int64)
    return r.view(np.dtype((np.void, r.itemsize * r.shape[1]))).ravel()


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (N, 3) float64 (zero for unused vertices)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # length = 2 * area
    n = np.zeros((len(v), 3))
    for k in range(3):
        for a in range(3):
            n[:, a] += np.bincount(f[:, k], weights=fn[:, a], minlength=len(v))
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)


def vertex_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """A third of the area of each vertex's faces, (N,) mm² (sums to the surface area)."""
    f = np.asarray(faces, np.int64)
    a = face_areas(vertices, f) / 3.0
    return np.bincount(f.ravel(), weights=np.repeat(a, 3), minlength=len(vertices))
