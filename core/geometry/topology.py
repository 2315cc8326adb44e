"""Topological invariants of triangle meshes: edges, components, closed, manifold, oriented, genus.

For a closed 2-manifold with ``C`` components, Euler characteristic ``χ = V − E + F`` and genus
``g = (2C − χ) / 2`` (a sphere has χ = 2, g = 0; a torus χ = 0, g = 1). :func:`topology` counts
edges and fans vertex by vertex and components by union-find (numba, linear time); the edge list
itself (:func:`edge_face_counts`) is sorted once with ``np.unique``-style keys.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np

from ..model.mesh import degenerate_faces, face_areas
from . import _neighbors_kernels, _topology_kernels


def directed_edges(faces: np.ndarray) -> np.ndarray:
    """All half-edges (3M, 2) int64 as (from, to), in face order: face f gives rows 3f..3f+2."""
    f = np.asarray(faces, dtype=np.int64)
    return np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)


def _edge_keys(a: np.ndarray, b: np.ndarray, n_vertices: int) -> np.ndarray:
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    return lo * np.int64(max(n_vertices, 1)) + hi


def edge_face_counts(faces: np.ndarray, n_vertices: int):
    """Undirected edges with how many faces use them and their net orientation.

    Returns
    -------
    edges : (E, 2) int64, sorted vertex pairs (lo, hi)
    count : (E,) int64, faces using each edge
    balance : (E,) int64, (#half-edges lo→hi) − (#hi→lo); 0 for every edge of a consistently
        oriented closed manifold.
    """
    he = directed_edges(faces)
    if he.size == 0:
        z = np.zeros(0, np.int64)
        return np.zeros((0, 2), np.int64), z, z
    keys = _edge_keys(he[:, 0], he[:, 1], n_vertices)
    sign = np.where(he[:, 0] < he[:, 1], 1, -1)
    order = np.argsort(keys, kind="stable")
    ks = keys[order]
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    count = np.diff(np.r_[starts, ks.size])
    balance = np.add.reduceat(sign[order], starts)
    uk = ks[starts]
    n = np.int64(max(n_vertices, 1))
    edges = np.stack([uk // n, uk % n], axis=1)
    return edges, count, balance


def face_components(faces: np.ndarray, n_vertices: int) -> Tuple[int, np.ndarray]:
    """Connected components of faces through shared vertices.

    Returns ``(n_components, labels)`` with ``labels`` (M,) int64 in [0, n_components),
    numbered by each component's smallest vertex index. Faces touching only at a vertex count as
    connected (printing-wise they are one part).
    """
    f = _index_array(faces)
    if f.shape[0] == 0:
        return 0, np.zeros(0, np.int64)
    n = max(int(n_vertices), int(f.max()) + 1)
    count, labels = _topology_kernels.face_components(f, n)
    return int(count), labels


def _index_array(faces: np.ndarray) -> np.ndarray:
    """Faces as a C-contiguous (M, 3) int32 (int64 when indices need it), copied only if needed."""
    f = np.asarray(faces)
    if f.dtype == np.int64 and f.size and int(f.max()) >= 2**31:
        return np.ascontiguousarray(f)
    return np.ascontiguousarray(f, dtype=np.int32).reshape(-1, 3)


@dataclass
class Topology:
    """Invariants of one triangle mesh (see :func:`topology`)."""

    vertices: int
    faces: int
    edges: int
    components: int
    euler: int
    genus: Optional[int]
    closed: bool
    manifold: bool
    oriented: bool
    boundary_edges: int
    nonmanifold_edges: int
    nonmanifold_vertices: int
    degenerate_faces: int

    def as_dict(self) -> Dict:
        return dict(self.__dict__)


def topology(vertices: np.ndarray, faces: np.ndarray, min_area: float = 0.0) -> Topology:
    """Check a mesh: closed, 2-manifold (edges and vertices), consistently oriented, genus.

    * closed: every edge has exactly two faces;
    * manifold: no edge has more than two faces and every vertex's faces form one fan;
    * oriented: every edge used once in each direction (needs closed + manifold);
    * genus: ``(2C − χ) / 2`` for closed manifolds, else None.
    Only vertices used by faces count in V. Linear time (numba passes per face and per vertex);
    meshes with faces that repeat a vertex index go through the sorted edge list instead.
    """
    return topology_and_size(vertices, faces, min_area)[0]


def topology_and_size(vertices: np.ndarray, faces: np.ndarray, min_area: float = 0.0,
                      by_position: bool = False) -> Tuple[Topology, float, float]:
    """``(topology, area mm², enclosed volume mm³)``: :func:`topology` and
    :func:`area_and_volume` from one pass over the faces (a report's per-surface facts).

    ``by_position``: the topology of the surface as a file reader sees it, vertices at the same
    float32 position joined (:func:`position_ids`; STL stores positions only, and slicers and
    mesh tools merge them), not the vertex indices."""
    v = _point_array(vertices)
    f = _index_array(faces)
    if by_position and f.shape[0]:
        ids, distinct = position_ids(v)
        if distinct < v.shape[0]:
            v, f = v[np.unique(ids, return_index=True)[1]], np.ascontiguousarray(ids[f], np.int32)
    if f.shape[0] == 0:
        return Topology(0, 0, 0, 0, 0, None, False, True, True, 0, 0, 0, 0), 0.0, 0.0
    area, volume, ndeg, repeated = _topology_kernels.face_measures(v, f, float(min_area))
    if repeated:
        return _topology_sorted(v, f, min_area), float(area), float(volume)
    return _topology_linear(v, f, int(ndeg)), float(area), float(volume)


def _topology_linear(v: np.ndarray, f: np.ndarray, ndeg: int) -> Topology:
    """:func:`topology` of faces that repeat no vertex index (numba passes per vertex)."""
    nv_all = int(v.shape[0])
    F = int(f.shape[0])
    vf_offsets, vf = _neighbors_kernels.vertex_faces(f, np.int64(max(nv_all, int(f.max()) + 1)))
    E, boundary, nm_edges, unoriented, nm_verts, V = _topology_kernels.vertex_topology(f, vf_offsets, vf)
    ncomp, _ = face_components(f, nv_all)
    closed = boundary == 0 and nm_edges == 0
    manifold = nm_edges == 0 and nm_verts == 0
    euler = V - E + F
    genus = None
    if closed and manifold and (2 * ncomp - euler) % 2 == 0:
        genus = (2 * ncomp - euler) // 2
    return Topology(int(V), F, int(E), ncomp, int(euler), genus, bool(closed), bool(manifold),
                    bool(unoriented == 0), int(boundary), int(nm_edges), int(nm_verts), int(ndeg))


def area_and_volume(vertices: np.ndarray, faces: np.ndarray) -> Tuple[float, float]:
    """``(area mm², enclosed volume mm³)`` in one linear pass; the volume as
    :func:`anatomesh.core.model.mesh.signed_volume` (positive for outward faces, exact for closed
    meshes), the area as :func:`anatomesh.core.model.mesh.surface_area`."""
    f = _index_array(faces)
    if f.shape[0] == 0:
        return 0.0, 0.0
    area, volume, _, _ = _topology_kernels.face_measures(_point_array(vertices), f, 0.0)
    return float(area), float(volume)


def position_ids(vertices: np.ndarray) -> Tuple[np.ndarray, int]:
    """``(ids (N,) int64, distinct)``: vertices at the same float32 position (as STL, PLY and GLB
    store them) get the same id, numbered 0, 1, ... in order of first appearance; linear time."""
    p = np.ascontiguousarray(vertices, np.float32).reshape(-1, 3) + np.float32(0.0)  # -0.0 → 0.0
    ids = np.empty(p.shape[0], np.int64)
    distinct = _topology_kernels.weld_positions(p.view(np.uint32), ids)
    return ids, int(distinct)


def _point_array(vertices: np.ndarray) -> np.ndarray:
    v = np.asarray(vertices)
    dtype = v.dtype if v.dtype in (np.float32, np.float64) else np.float64
    return np.ascontiguousarray(v, dtype=dtype).reshape(-1, 3)


def _topology_sorted(vertices: np.ndarray, faces: np.ndarray, min_area: float) -> Topology:
    """:func:`topology` through the sorted half-edge list (any mesh, degenerate faces too)."""
    f = np.asarray(faces, dtype=np.int64)
    nv_all = int(np.asarray(vertices).shape[0])
    edges, count, balance = edge_face_counts(f, nv_all)
    used = np.unique(f.ravel())
    V, E, F = int(used.size), int(edges.shape[0]), int(f.shape[0])
    boundary = int(np.count_nonzero(count == 1))
    nm_edges = int(np.count_nonzero(count > 2))
    closed = boundary == 0 and nm_edges == 0 and F > 0
    nm_verts = nonmanifold_vertices(f, nv_all).size
    manifold = nm_edges == 0 and nm_verts == 0
    oriented = bool(np.all(balance[count == 2] == 0)) if E else True
    ncomp, _ = face_components(f, nv_all)
    euler = V - E + F
    genus = None
    if closed and manifold and (2 * ncomp - euler) % 2 == 0:
        genus = (2 * ncomp - euler) // 2
    ndeg = int(degenerate_faces(vertices, f, min_area).size)
    return Topology(V, F, E, ncomp, euler, genus, closed, manifold, oriented, boundary,
                    nm_edges, int(nm_verts), ndeg)


def nonmanifold_vertices(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Vertices whose incident faces form more than one fan (pinch points), ascending int64.

    For each vertex, the faces around it are linked through the edges they share at that vertex;
    a manifold vertex has exactly one linked group. Works on any mesh (boundaries allowed).
    """
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if f.shape[0] == 0:
        return np.zeros(0, np.int64)
    vf_offsets, vf = _neighbors_kernels.vertex_faces(f, np.int64(max(n_vertices, int(f.max()) + 1)))
    return np.flatnonzero(_neighbors_kernels.fan_counts(f, vf_offsets, vf) > 1).astype(np.int64)


def component_sizes(vertices: np.ndarray, faces: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per connected component (:func:`face_components`): ``(labels (M,) int64 of the faces,
    volume (C,) mm³ by the divergence theorem, positive for outward faces, area (C,) mm²)``, in
    one pass over the faces. Each component's volume is taken about one of its own vertices, so
    large patient coordinates lose no precision."""
    f = _index_array(faces)
    n, lab = face_components(f, len(vertices))
    volumes, areas = np.zeros(n), np.zeros(n)
    if n:
        _topology_kernels.component_sums(np.ascontiguousarray(vertices), f, lab, n, volumes, areas)
    return lab, volumes, areas


def component_measures(vertices: np.ndarray, faces: np.ndarray) -> List[Dict]:
    """Per connected component: faces, area (mm²), volume (mm³), sorted by volume descending.

    Each entry is ``{"faces": index array, "area_mm2": float, "volume_mm3": float}``.
    """
    lab, volumes, areas = component_sizes(vertices, faces)
    n = volumes.size
    order = np.argsort(lab, kind="stable")
    groups = np.split(order, np.cumsum(np.bincount(lab, minlength=n))[:-1]) if n else []
    out = [{"faces": groups[c], "area_mm2": float(areas[c]), "volume_mm3": float(volumes[c])}
           for c in range(n)]
    out.sort(key=lambda d: -abs(d["volume_mm3"]))
    return out


def closed_and_oriented(faces: np.ndarray, n_vertices: int) -> bool:
    """Every edge has two faces using it once in each direction (closed and consistently
    oriented; pinch vertices allowed) — the cheap part of :func:`anatomesh.core.model.mesh.topology`
    that the ray directions need."""
    _, count, balance = edge_face_counts(faces, n_vertices)
    return bool(count.size and np.all(count == 2) and np.all(balance == 0))
